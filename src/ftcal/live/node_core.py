"""What a live node does whatever carries its messages (Zenoh, ROS 2): the calibrator between message callbacks,
commands and a diagnostics loop.

:class:`NodeCore` holds the pose sources (IMU, joint states with a robot model, else a fixed pose with gravity along
−z), the temperature, the stamp checks (stale, far-future, a publisher's clock restart), the counters of dropped
messages, the commands (re-tare, tool switch, identification) as plain text in and a JSON-ready reply out, the
diagnostics document, and the main thread's loop (silence, diagnostics as ROS's ``diagnostic_updater`` paces them).
:class:`ftcal.live.zenoh_node.LiveNode` and :class:`ftcal.live.ros2_node.Ros2Node` add only their transport.
"""

from __future__ import annotations

import math
import sys
import threading
import time

import numpy as np

from ..core.limits import (C_RUNTIME_MAX_TOOL_NAME, LIVE_CLOCK_RESTART_MESSAGES, LIVE_DIAGNOSTICS_MIN_INTERVAL_S,
                           LIVE_DIAGNOSTICS_PERIOD_S, LIVE_MAX_STAMP_JUMP_S, MAX_CELL_MAGNITUDE)
from ..runtime.errors import FtcalError
from .health import BIT, names_of

# Joint-name lists remembered (a JointState publisher keeps one list; a few are plenty).
MAX_JOINT_LISTS = 16
# A wrench stamped this much later than the newest joint state is not static (its pose may be out of date:
# the bias must not take up a tool wrench computed for another pose); counted in the diagnostics.
JOINT_MAX_AGE_S = 0.02
# The main thread wakes this often to check for silence (and at once when a flag changes).
WATCH_PERIOD_S = 0.05
# The commands a node takes; every one but status changes the calibrator.
COMMANDS = ("retare", "switch_tool", "identify_tool", "status")


class NodeCore:
    """The transport-independent part of a live node (see the module docstring).

    Parameters
    ----------
    live : LiveCalibrator
    robot : SensorGravity or None, gravity from joint states (``take_joints``)
    echo : print-like, for the one-line messages on stderr
    source : str, the wrench input's name in messages (a Zenoh key, a ROS topic)
    what : str, the option that chose the transport, for messages (``--zenoh``)
    """

    def __init__(self, live, *, robot=None, echo=print, source: str = "ft/raw", what: str = "--zenoh") -> None:
        if live.model is not None and len(live.model.input_names_) != 6:
            raise FtcalError(f"{what}: the model takes {len(live.model.input_names_)} inputs; a WrenchStamped "
                             "carries 6 channels.")
        self.live, self.echo, self.robot, self.source = live, echo, robot, source
        self.lock = threading.Lock()  # the calibrator: message callbacks, commands, diagnostics
        self.wake = threading.Event()  # a flag changed: publish diagnostics now
        self.gravity: tuple | None = (0.0, 0.0, -live.gravity_magnitude)
        self.quaternion: tuple | None = None
        self.temperature: float | None = None
        self.signal_key = "raw" if live.model is not None else "wrench"
        self.pose: tuple | None = None  # (gravity, joint positions, stamp) from the latest joint state
        self.joint_sources: dict = {}  # joint-name tuple -> (SensorGravity over them, their indices), or None
        self.waiting_for_joints = 0
        self.stale_joints = 0
        self.bad_messages = 0
        self.stale_samples = 0
        self.stamp_jumps = 0  # wrenches held back: stamped more than LIVE_MAX_STAMP_JUMP_S after the last one
        self.held_stamp: float | None = None  # the last of them, confirmed by a next message that follows it
        self.stale_run: tuple | None = None  # (count, stamp) of the stale messages in a row that keep their order
        self.raised = 0  # flag bits raised since the last diagnostics message (a contact may last one sample)
        self.closing = False  # set when the node shuts down: callbacks still in flight stop publishing
        self.last_message = time.monotonic()

    # ----- messages in --------------------------------------------------------------------------------------
    def process_wrench(self, stamp_ns: int, values):
        """One wrench (or a 6-input model's raw channels) through the calibrator.

        Returns
        -------
        (LiveSample, flags before, flags after), or None when the message is dropped (counted: stale, held back,
        waiting for joints, refused by the calibrator).
        """
        self.last_message = time.monotonic()
        t = stamp_ns * 1e-9
        if self.robot is not None:
            pose = self.pose
            if pose is None:
                self.waiting_for_joints += 1
                return None
            source = {"gravity": pose[0], "joints": pose[1]}
            if t - pose[2] > JOINT_MAX_AGE_S:
                source["static"] = False
                self.stale_joints += 1
        elif self.quaternion is not None:
            source = {"quaternion": self.quaternion}
        else:
            source = {"gravity": self.gravity}
        if self.temperature is not None:
            source["temperature"] = self.temperature
        with self.lock:
            if not self._in_time(t):
                return None
            before = self.live.flags_now
            if before & BIT["silent"]:
                self.live.set_silent(False, "messages again")
                self.echo(f"ftcal live: messages again on {self.source}", file=sys.stderr, flush=True)
            try:
                result = self.live.step(t, **{self.signal_key: values}, **source)
            except FtcalError:
                self.bad_messages += 1
                return None
            after = self.live.flags_now
            if after != before:
                self.raised |= after & ~before
        return result, before, after

    def announce(self, t: float, result, before: int, after: int) -> None:
        """After the answers are out: wake the diagnostics on a flag change, and say each flag newly raised."""
        if after != before:
            self.wake.set()
            for flag, reason in result.flags.items():  # contacts come and go: diagnostics carry them
                if flag != "contact" and not before & BIT[flag]:
                    self.echo(f"ftcal live: t={t:.3f} s {flag}: {reason}", file=sys.stderr, flush=True)

    def _in_time(self, t: float) -> bool:
        """Whether a wrench stamped ``t`` goes to the calibrator (under the lock); counts those that do not.

        Older than the last sample: stale. Later than it by more than :data:`LIVE_MAX_STAMP_JUMP_S`: held back
        (``stamp_jumps``) until the next message confirms the new time line, so that one far-future stamp cannot
        make every later message stale. After :data:`LIVE_CLOCK_RESTART_MESSAGES` − 1 stale messages in a row that keep
        their own order (the publisher's clock restarted), the next one restarts the calibrator's clock.
        """
        last = self.live.last_time
        if last is not None and t <= last:
            run = self.stale_run
            self.stale_run = (run[0] + 1, t) if run and t > run[1] else (1, t)
            if self.stale_run[0] < LIVE_CLOCK_RESTART_MESSAGES:
                self.stale_samples += 1
                return False
            reason = (f"stamps on {self.source} went back from t={last:.9g} s to t={t:.9g} s for "
                      f"{LIVE_CLOCK_RESTART_MESSAGES} messages: the clock restarts there")
            self.live.restart_clock(reason)
            self.echo(f"ftcal live: {reason}", file=sys.stderr, flush=True)
        self.stale_run = None
        if last is not None and t - last > LIVE_MAX_STAMP_JUMP_S:
            held, self.held_stamp = self.held_stamp, t
            if held is None or not 0.0 < t - held <= LIVE_MAX_STAMP_JUMP_S:
                self.stamp_jumps += 1
                return False
        self.held_stamp = None
        return True

    def take_imu(self, q, orientation_covariance: float, acceleration) -> None:
        """An IMU reading: the orientation when it is a unit quaternion (and its covariance does not start with -1,
        ``sensor_msgs/msg/Imu``'s "no orientation"), else gravity = minus a finite, non-zero acceleration of at most
        1e100; otherwise a bad message, and the pose from the previous message is kept."""
        q, acceleration = tuple(map(float, q)), tuple(map(float, acceleration))
        norm_a = math.sqrt(sum(a * a for a in acceleration)) if all(map(math.isfinite, acceleration)) else math.nan
        if orientation_covariance != -1.0 and abs(math.sqrt(sum(v * v for v in q)) - 1.0) < 1e-3:
            self.quaternion = q
        elif 0.0 < norm_a <= MAX_CELL_MAGNITUDE:
            self.quaternion, self.gravity = None, tuple(-a for a in acceleration)
        else:
            self.bad_messages += 1

    def take_temperature(self, value: float) -> None:
        """A temperature reading (°C, ``sensor_msgs/msg/Temperature``), used with every later wrench; a non-finite or
        beyond-1e100 one is a bad message and the previous one is kept."""
        value = float(value)
        if math.isfinite(value) and abs(value) <= MAX_CELL_MAGNITUDE:
            self.temperature = value
        else:
            self.bad_messages += 1

    def take_joints(self, names, positions, stamp: float, source: str) -> None:
        """A joint state: gravity in the sensor frame from the joints of the robot model named in it (a
        :class:`~ftcal.robot.kinematics.SensorGravity` built once per list of names)."""
        names, positions = tuple(names), np.asarray(positions, dtype=float)
        if names not in self.joint_sources:
            if len(self.joint_sources) >= MAX_JOINT_LISTS:
                self.joint_sources.clear()
            known = set(self.robot.robot.joint_names)
            keep = [i for i, name in enumerate(names) if name in known]
            try:
                self.joint_sources[names] = (self.robot.with_joints([names[i] for i in keep], source), keep)
            except FtcalError as exc:  # e.g. a joint of the sensor's chain is missing: say so once per list
                self.joint_sources[names] = None
                self.echo(f"ftcal live: {exc}", file=sys.stderr, flush=True)
        found = self.joint_sources[names]
        if found is None or positions.shape != (len(names),) or not np.all(np.isfinite(positions[found[1]])):
            self.bad_messages += 1
            return
        q = positions[found[1]]
        self.pose = (found[0].one(q), tuple(q.tolist()), stamp)

    # ----- commands -----------------------------------------------------------------------------------------
    def command(self, name: str, text: str) -> dict:
        """Run command ``name`` (:data:`COMMANDS`) on its text argument: ``{"ok": True, ..., "status": ...}``, or
        ``{"ok": False, "error": ...}`` naming what is wrong (bad input, or an unexpected failure: the caller is
        always answered)."""
        actions = {"retare": lambda _: _warned(self.live.retare()),
                   "switch_tool": lambda tool: self.live.switch_tool(tool.strip()),
                   "identify_tool": self._identify, "status": lambda _: None}
        try:
            with self.lock:
                result = actions[name](text)
                status = self.live.status()
            return {"ok": True, **(result or {}), "status": status}
        except FtcalError as exc:
            return {"ok": False, "error": str(exc)}
        except Exception as exc:  # a bug must not leave the caller waiting: answer, and the node runs on
            return {"ok": False, "error": f"{name}: {type(exc).__name__}: {exc}"}

    def _identify(self, text: str) -> dict:
        words = text.split()
        if len(words) == 2 and words[0] == "start":
            self.live.start_identification(tool_name(words[1]))
            return {}
        if words == ["finish"]:
            payload = self.live.finish_identification()
            return {"mass": payload.mass, "mass_stderr": float(payload.stderr["mass"]), "com": payload.com.tolist()}
        raise FtcalError("identify_tool takes 'start NAME' or 'finish'.")

    # ----- diagnostics and the main thread -------------------------------------------------------------------
    def diagnostics_status(self) -> dict:
        """The calibrator's status, the reasons of its flags, the flags raised since the previous call with their
        reasons (``raised``), and the node's counters; starts a new ``raised`` (under the lock)."""
        status = self.live.status()
        status["reasons"] = {name: self.live.reason_of(name) for name in status["flags"]}
        raised, self.raised = self.raised, 0
        status["raised"] = {name: self.live.reason_of(name) for name in names_of(raised)}
        status["bad_messages"], status["stale_samples"] = self.bad_messages, self.stale_samples
        status["stamp_jumps"] = self.stamp_jumps
        status["waiting_for_joints"], status["stale_joints"] = self.waiting_for_joints, self.stale_joints
        return status

    def run_loop(self, duration: float | None, silence: float, publish) -> None:
        """The main thread until ``duration`` (None: until interrupted): raise ``silent`` after ``silence`` s without
        a wrench, and call ``publish()`` (which returns the flag bits it reported) every
        :data:`LIVE_DIAGNOSTICS_PERIOD_S` and at once on a flag change, no sooner than
        :data:`LIVE_DIAGNOSTICS_MIN_INTERVAL_S` after the previous call (ROS's ``diagnostic_updater``: a period and
        ``force_update()``)."""
        started = time.monotonic()
        self.last_message = started
        last_diagnostics = -math.inf
        flags_sent = -1
        while duration is None or time.monotonic() - started < duration:
            now = time.monotonic()
            if now - self.last_message > silence and not self.live.flags_now & BIT["silent"]:
                reason = f"no message on {self.source} for {silence:g} s"
                with self.lock:
                    self.live.set_silent(True, reason)
                self.echo(f"ftcal live: {reason}", file=sys.stderr, flush=True)
            changed = self.live.flags_now != flags_sent or self.raised
            due = last_diagnostics + (LIVE_DIAGNOSTICS_MIN_INTERVAL_S if changed else LIVE_DIAGNOSTICS_PERIOD_S)
            if now >= due:
                flags_sent, last_diagnostics = publish(), now
                due = now + LIVE_DIAGNOSTICS_PERIOD_S
            self.wake.wait(timeout=max(0.0, min(WATCH_PERIOD_S, silence, due - now)))
            self.wake.clear()

    def save_on_exit(self) -> None:
        """The state, saved on the way out when there is a state file and a sample went through."""
        if self.live.state_path is not None and self.live.last_time is not None:
            self.live.save_state()


def _warned(warning: str | None) -> dict | None:
    return None if warning is None else {"warning": warning}


def tool_name(name: str) -> str:
    """A tool name from the network: at most :data:`~ftcal.core.limits.C_RUNTIME_MAX_TOOL_NAME` UTF-8 bytes (what the
    C runtime's slots hold) and no control, format (e.g. U+202E, right-to-left override) or separator characters
    that would hide or reorder text in logs and terminals."""
    import unicodedata

    size = len(name.encode("utf-8"))
    if size > C_RUNTIME_MAX_TOOL_NAME:
        raise FtcalError(f"tool name of {size} bytes; at most {C_RUNTIME_MAX_TOOL_NAME} (UTF-8).")
    odd = next((c for c in name if unicodedata.category(c)[0] == "C" or unicodedata.category(c) in ("Zl", "Zp")), None)
    if odd is not None:
        raise FtcalError(f"tool name {name!r} has the character U+{ord(odd):04X} ({unicodedata.category(odd)}); "
                         "give letters, digits and punctuation.")
    return name
