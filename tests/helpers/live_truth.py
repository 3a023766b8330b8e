"""An own truth generator for the live tracker: the world, not the tracker's model.

A 1.2 kg tool on a wrist sensor. First an identification recording (still holds in varied orientations), identified
as a user would (``payload --bias-drift random-walk``); then an operation that breaks the tracker's assumptions: a
faster walk than identified, a warm-up ramp, a Gauss-Markov wander with quantisation; with contacts of three kinds
(steps held in a pose, slow ramps, short touches), all on the force axes with their torque at 5 cm. Holds
alternate with smooth moves (slerp); the tracker gets quaternions, so its motion test decides what is static.

:func:`score` gives what issue 40 asks: contact-free compensated force RMS over the noise floor, the share of
contact-free static samples flagged, the share of contact samples beyond 4 noise floors flagged, and the largest
bias change across a contact (bias after − before, less the true drift over it).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

MASS, COM = 1.2, np.array([0.004, -0.003, 0.06])
SCALE = np.r_[np.ones(3), np.full(3, 0.1)]  # torque noise and walk a tenth of force's (N·m)


@dataclass(frozen=True)
class World:
    """How the sensor behaves: white noise, wander (Gauss-Markov), quantisation, walk, warm-up ramp (force, N)."""

    white: float = 0.05
    wander: float = 0.0
    tau: float = 2.0
    lsb: float = 0.0
    walk: float = 3.0  # N/√h
    ramp: float = 0.0  # N/h, exponential warm-up of time constant 20 min (its slope at the start)

    @property
    def floor(self) -> float:
        """Per-sample noise std of one force axis about the bias."""
        return float(np.sqrt(self.white ** 2 + self.wander ** 2 + self.lsb ** 2 / 12.0))


def _unit(x):
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def _wander(rng, n, sigma, tau, dt):
    if sigma == 0.0:
        return np.zeros((n, 6))
    phi = np.exp(-dt / tau)
    kick = rng.normal(size=(n, 6)) * sigma * np.sqrt(1.0 - phi * phi)
    kick[0] = rng.normal(size=6) * sigma
    # x_k = φ x_(k-1) + kick_k as a linear filter
    from scipy.signal import lfilter

    return lfilter([1.0], [1.0, -phi], kick, axis=0)


def session(world: World, duration: float, rate: float, hold_s: float, move_s: float, seed: int,
            contacts=(), bias0=None):
    """Readings and truth of one session.

    Returns
    -------
    dict: time, quaternion, gravity, wrench, bias, contact (n, 6), holding (n,) bool
    """
    from scipy.spatial.transform import Rotation, Slerp

    rng = np.random.default_rng(seed)
    n = int(round(duration * rate))
    dt = 1.0 / rate
    t = np.arange(n) * dt
    period = hold_s + move_s
    n_poses = int(np.ceil(duration / period)) + 2
    # gravity directions over the lower half-sphere of tool-down poses, tilted up to 80°
    tilt, turn = np.radians(rng.uniform(0, 80, n_poses)), rng.uniform(0, 2 * np.pi, n_poses)
    poses = Rotation.from_euler("zyz", np.c_[turn, tilt, rng.uniform(0, 2 * np.pi, n_poses)])
    k = np.minimum((t // period).astype(int), n_poses - 2)
    phase = t - k * period
    holding = phase < hold_s
    blend = np.clip((phase - hold_s) / move_s, 0.0, 1.0)
    blend = blend * blend * (3.0 - 2.0 * blend)
    q = np.empty((n, 4))
    for pose in np.unique(k):
        rows = k == pose
        q[rows] = Slerp([0.0, 1.0], Rotation.concatenate([poses[pose], poses[pose + 1]]))(blend[rows]).as_quat()
    gravity = Rotation.from_quat(q).inv().apply([0.0, 0.0, -9.81])
    walk = np.cumsum(rng.normal(size=(n, 6)) * world.walk / np.sqrt(3600.0) * np.sqrt(dt), axis=0) * SCALE
    signs = rng.choice([-1.0, 1.0], 6)
    warm = world.ramp / 3600.0 * 1200.0 * (1.0 - np.exp(-t / 1200.0))  # slope world.ramp N/h at t = 0
    bias = (np.r_[1.0, -2.0, 0.5, 0.1, 0.05, -0.1] if bias0 is None else bias0) + walk + np.outer(warm, signs * SCALE)
    tool = np.zeros((n, 6))
    tool[:, :3] = MASS * gravity
    tool[:, 3:] = np.cross(MASS * COM, gravity)
    contact = np.zeros((n, 6))
    for start, length, force, kind in contacts:
        rows = (t >= start) & (t < start + length)
        direction = _unit(rng.normal(size=3))
        if kind == "ramp":  # up over the whole contact, then released in 50 ms
            shape = np.clip((t[rows] - start) / length, 0, 1) * np.clip((start + length - t[rows]) / 0.05, 0, 1)
        else:  # step or touch: 50 ms edges
            shape = np.clip(np.minimum(t[rows] - start, start + length - t[rows]) / 0.05, 0.0, 1.0)
        f = force * direction * shape[:, None]
        contact[rows, :3] = f
        contact[rows, 3:] = np.cross([0.0, 0.0, 0.05], f)
    noise = SCALE * (rng.normal(size=(n, 6)) * world.white + _wander(rng, n, world.wander, world.tau, dt))
    wrench = bias + tool + contact + noise
    if world.lsb > 0:
        wrench = np.round(wrench / (world.lsb * SCALE)) * (world.lsb * SCALE)
    return {"time": t, "quaternion": q, "gravity": gravity, "wrench": wrench, "bias": bias, "contact": contact,
            "holding": holding}


def identify(world: World, seed: int = 11, rate: float = 100.0):
    """``payload --bias-drift random-walk`` on a 4-minute identification recording of the world (holds only)."""
    from ftcal.payload.kinematics import Kinematics
    from ftcal.payload.parameters import PayloadParameters
    from ftcal.payload.tables import PayloadRecording, identify_recording

    rec = session(world, 240.0, rate, 8.0, 2.0, seed)
    keep = rec["holding"]
    recording = PayloadRecording(rec["wrench"][keep], Kinematics(rec["gravity"][keep]), np.zeros(keep.sum(), int),
                                 rec["time"][keep], None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = identify_recording(recording, bias_drift="random-walk", time_column="time", cross_validate=False)
    return PayloadParameters.from_fit(fit.fit, gravity=9.81, frame=None, reaction=False,
                                      wrench_columns=("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), drift=fit.drift)


# Contacts of an operation (start s, length s, force N, kind): steps held, a slow ramp, touches.
CONTACTS = ((40.0, 4.0, 10.0, "step"), (70.0, 6.0, 6.0, "ramp"), (100.0, 0.6, 3.0, "touch"),
            (120.0, 3.0, 2.0, "step"), (140.0, 0.8, 3.0, "touch"), (160.0, 5.0, 15.0, "step"))


def operation(world: World, seed: int = 5, rate: float = 100.0, duration: float = 180.0):
    """The operation: holds of 6 s, moves of 2 s, :data:`CONTACTS` (each inside a hold)."""
    # contacts start 1 s into a hold so that the motion test calls them static
    period = 8.0
    placed = tuple((np.floor(s / period) * period + 1.0, min(length, 4.5), f, kind) for s, length, f, kind in CONTACTS)
    return session(world, duration, rate, 6.0, 2.0, seed, placed), placed


def replay(live, rec, block: int | None = None):
    """Run the calibrator over the session (in blocks, or one step at a time when ``block`` is None)."""
    if block is not None:
        parts = [live.run(rec["time"][a:a + block], wrench=rec["wrench"][a:a + block],
                          quaternion=rec["quaternion"][a:a + block]) for a in range(0, rec["time"].size, block)]
        return {"compensated": np.vstack([p.compensated for p in parts]), "bias": np.vstack([p.bias for p in parts]),
                "flags": np.concatenate([p.flags for p in parts]), "static": np.concatenate([p.static for p in parts])}
    out = {"compensated": [], "bias": [], "flags": [], "static": []}
    from ftcal.live.health import BIT

    for k in range(rec["time"].size):
        s = live.step(rec["time"][k], wrench=rec["wrench"][k], quaternion=rec["quaternion"][k])
        out["compensated"].append(s.compensated)
        out["bias"].append(s.bias)
        out["flags"].append(sum(BIT[name] for name in s.flags))
        out["static"].append(s.static)
    return {key: np.asarray(v) for key, v in out.items()}


def score(world: World, rec, out, contacts, settle: float = 20.0) -> dict:
    """Issue 40's numbers, from ``settle`` s on (before it the bias is being acquired)."""
    from ftcal.live.health import BIT

    t = rec["time"]
    floor = world.floor
    contact_force = np.linalg.norm(rec["contact"][:, :3], axis=1)
    near = np.zeros(t.size, bool)  # contacts and 1 s after (the filter's lag)
    for start, length, _, _ in contacts:
        near |= (t >= start - 0.1) & (t < start + length + 1.0)
    late = t >= settle
    free = late & ~near & rec["holding"]
    static_free = free & out["static"]
    flagged = (out["flags"] & (BIT["contact"] | BIT["unexplained"])) != 0
    error = out["compensated"][:, :3] - (rec["wrench"][:, :3] - rec["wrench"][:, :3])  # contact-free: truth is 0
    rms = float(np.sqrt(np.mean(error[free] ** 2)))
    big = late & (contact_force > 4.0 * floor)
    absorbed = 0.0
    for start, length, _, _ in contacts:
        if start < settle:
            continue
        a, b = np.searchsorted(t, start - 0.1), np.searchsorted(t, start + length + 0.5)
        moved = (out["bias"][b, :3] - out["bias"][a, :3]) - (rec["bias"][b, :3] - rec["bias"][a, :3])
        absorbed = max(absorbed, float(np.abs(moved).max()))
    bias_error = float(np.sqrt(np.mean((out["bias"][free, :3] - rec["bias"][free, :3]) ** 2)))
    return {"floor": floor, "free_rms": rms, "free_over_floor": rms / floor,
            "false_flags": float(flagged[static_free].mean()) if static_free.any() else 0.0,
            "contact_flagged": float(flagged[big].mean()) if big.any() else 1.0,
            "absorbed": absorbed, "bias_error": bias_error}


CASES = {
    "matched": (World(walk=3.0), World(walk=3.0)),
    "walk 3x": (World(walk=3.0), World(walk=9.0)),
    "walk 2x + warm-up 40 N/h": (World(walk=3.0), World(walk=6.0, ramp=40.0)),
    "coloured + quantised": (World(white=0.02, wander=0.25, tau=2.0, lsb=0.02, walk=3.0),
                             World(white=0.02, wander=0.25, tau=2.0, lsb=0.02, walk=3.0)),
    # the operation's noise 3x the identified (another day, a loose cable) and a 10-bit-like sensor whose step is
    # twice its white noise, walking 2x the identified
    "noise 3x": (World(walk=3.0), World(white=0.15, walk=3.0)),
    "10-bit steps, walk 2x": (World(white=0.05, lsb=0.1, walk=3.0), World(white=0.05, lsb=0.1, walk=6.0)),
}
# Issue 40's targets: (free force / floor, false flags, contacts flagged, bias absorbed N)
TARGETS = {"matched": (1.5, 0.01, 0.90, 0.3)}
OTHER_TARGETS = (3.0, 0.05, 0.90, 0.5)


# Seeds of (identification, operation): run_case's default first, then the ones the bench and tests add.
SEEDS = ((11, 5), (12, 6), (13, 7), (14, 8), (15, 9))


def run_case(name: str, block: int | None = 4096, seeds: tuple[int, int] = SEEDS[0], **calibrator) -> dict:
    """Identify in the case's identification world, operate in its operation world, score."""
    from ftcal.live import LiveCalibrator

    ident, oper = CASES[name]
    payload = identify(ident, seed=seeds[0])
    rec, contacts = operation(oper, seed=seeds[1])
    live = LiveCalibrator(tools={"tool": payload}, tool="tool", **calibrator)
    out = replay(live, rec, block)
    result = score(oper, rec, out, contacts)
    result["events"] = [e for e in live.events if e[1] in ("bias", "tracker")]
    return result
