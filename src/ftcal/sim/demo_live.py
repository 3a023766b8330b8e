"""``ftcal demo --scenario live``: a drifting wrist sensor in operation, its tools identified offline, then replayed live.

1. Each tool (gripper, drill) is identified offline the usual way (``ftcal payload --bias-drift
   random-walk`` on a recording of static poses): ``gripper.json``, ``drill.json``.
2. An operation recording (``live.parquet``: time, orientation qx..qw, wrench Fx..Tz): the bias
   walks and ramps, the arm holds poses and moves between them, a 10 N contact is held 5 s at
   :data:`CONTACT_AT`, the gripper is swapped for the drill at :data:`SWAP_AT`.
3. The live calibrator replays it (``replayed.parquet``) with the swap scripted, and is scored
   against the simulation's truth: bias error online, with no tracking (held at the first tare) and
   by the offline smoother on the whole recording; the contact flagged and not absorbed; the
   compensated wrench on static, contact-free samples against the noise.
"""

from __future__ import annotations

import dataclasses
import json
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .live_scenario import LiveScenario, simulate_live

# The same times at both sizes, so README commands that script them run after `--quick` too.
SWAP_AT = 61.0  # s, one second into a hold
CONTACT_AT = 30.5  # s, half a second into a hold
RETARE_AT = 100.0  # s, the README's scripted re-tare (inside a hold)
AXES = ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
GRAVITY = ("gx", "gy", "gz")  # the gravity columns handed to the payload step
NAMES = {"recording": "live.parquet", "replayed": "replayed.parquet", "summary": "summary.json"}


@dataclass(frozen=True)
class LiveDemoConfig:
    out_dir: Path = Path("ftcal-live-demo")
    seed: int = 0
    quick: bool = False


def _operation(config: LiveDemoConfig) -> LiveScenario:
    return LiveScenario(duration=120.0 if config.quick else 600.0, rate=200.0 if config.quick else 500.0,
                        hold_s=6.0, move_s=1.5, swaps=((SWAP_AT, "drill"),), contacts=((CONTACT_AT, 5.0, 10.0),),
                        seed=config.seed)


def identify_tool(name: str, scenario: LiveScenario, seed: int):
    """Identify one tool offline from static poses, as ``ftcal payload --bias-drift random-walk`` does."""
    from ..payload.parameters import PayloadParameters

    tools = {name: scenario.tools[name]}
    rec = simulate_live(dataclasses.replace(scenario, duration=180.0, rate=100.0, hold_s=4.0, move_s=1.0,
                                            tools=tools, swaps=(), contacts=(), seed=seed))
    result = _identified(rec, rec.holding)
    # Built from the step's fit rather than its `payload`, which adds the gain note to the file's fit record.
    return PayloadParameters.from_fit(result.fit, gravity=9.81, frame="ft_sensor", reaction=False,
                                      wrench_columns=AXES, drift=result.drift.drift)


def _identified(rec, keep):
    """The payload step (bias as a random walk, one group) on the samples ``keep`` of a simulated recording.

    The samples are the simulation's holds, so all are kept (``keep_moving``) rather than found again."""
    import pandas as pd

    from ..workflow import identify_payload

    frame = pd.DataFrame({"time": rec.time[keep], **{a: rec.wrench[keep, j] for j, a in enumerate(AXES)},
                          **{c: rec.gravity[keep, j] for j, c in enumerate(GRAVITY)}})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return identify_payload(frame, inputs=AXES, keep_moving=True, bias_drift="random-walk",
                                gravity_columns=GRAVITY)


def run_live_demo(config: LiveDemoConfig = LiveDemoConfig()) -> dict:
    """Run the scenario, write its files into ``config.out_dir`` and return the summary."""
    from ..files.payload_json import save_payload
    from ..runtime.atomic import write_text_atomic
    from ..workflow import LiveSetup, replay_live

    started = time.perf_counter()
    out = Path(config.out_dir)
    scenario = _operation(config)
    files, payloads = [], {}
    for k, name in enumerate(scenario.tools):
        payloads[name] = identify_tool(name, scenario, seed=1000 + 10 * config.seed + k)
        save_payload(payloads[name], out / f"{name}.json", sources=["ftcal demo --scenario live"])
        files.append(str(out / f"{name}.json"))
    rec = simulate_live(scenario)
    from ..data.tables import write_table

    write_table(rec.frame(), out / NAMES["recording"])
    files.append(str(out / NAMES["recording"]))
    replay = replay_live(out / NAMES["recording"], LiveSetup(tools=payloads, mount="gripper"),
                         output=out / NAMES["replayed"], inputs=AXES,
                         orientation=("qx", "qy", "qz", "qw"), switch_tool=[(SWAP_AT, "drill")]).replay
    files.append(str(out / NAMES["replayed"]))
    summary = score(rec, out / NAMES["replayed"], scenario)
    summary.update({"n_samples": int(rec.time.size), "replay_samples_per_s": replay.n_samples / replay.seconds,
                    "replay_cpu_s": replay.cpu_seconds, "replay_wall_s": replay.seconds,
                    "tools": {n: {"mass": p.mass, "mass_stderr": float(p.stderr["mass"])} for n, p in payloads.items()},
                    "true_mass": {n: t.mass for n, t in scenario.tools.items()},
                    "elapsed_s": time.perf_counter() - started})
    write_text_atomic(out / NAMES["summary"], json.dumps(summary, indent=1) + "\n")
    files.append(str(out / NAMES["summary"]))
    summary["files"] = files
    return summary


def score(rec, replayed: Path, scenario: LiveScenario) -> dict:
    """The replay against the simulation's truth, and the offline smoother on the same recording."""
    import pandas as pd

    from ..live.health import BIT

    table = pd.read_parquet(replayed)
    bias = table[[f"bias_{a}" for a in AXES]].to_numpy()
    compensated = table[list(AXES)].to_numpy()
    flags = table["flags"].to_numpy()
    known = np.arange(rec.time.size) >= int(np.argmax(table["updated"].to_numpy()))
    online = np.sqrt(np.mean((bias - rec.bias)[known] ** 2, axis=0))
    untracked = np.sqrt(np.mean((rec.bias - rec.bias[known][0])[known] ** 2, axis=0))
    keep = rec.holding & ~np.any(rec.contact != 0, axis=1)
    # The offline smoother needs one tool: fit it on the samples before the swap.
    first = keep & (rec.tool == rec.tool[0])
    drift = _identified(rec, first).drift.drift
    before = known & (rec.time <= rec.time[first][-1]) & (rec.time >= rec.time[first][0])
    smoothed = np.column_stack([np.interp(rec.time, drift.knot_times, drift.knot_bias[:, j]) for j in range(6)])
    smoother = np.sqrt(np.mean((smoothed - rec.bias)[before] ** 2, axis=0))
    online_before = np.sqrt(np.mean((bias - rec.bias)[before] ** 2, axis=0))
    pressing = np.linalg.norm(rec.contact[:, :3], axis=1) >= 5.0
    window = (rec.time >= CONTACT_AT - 0.1) & (rec.time <= CONTACT_AT + 5.1)
    absorbed = float(np.linalg.norm(bias[window, :3] - bias[window][0, :3], axis=1).max()
                     - np.linalg.norm(rec.bias[window, :3] - rec.bias[window][0, :3], axis=1).max())
    quiet = table["static"].to_numpy() & ~np.any(rec.contact != 0, axis=1) & known
    noise = np.r_[np.full(3, scenario.noise[0]), np.full(3, scenario.noise[1])]
    return {"bias_rms_online": online.tolist(), "bias_rms_untracked": untracked.tolist(),
            "bias_rms_online_first_tool": online_before.tolist(), "bias_rms_smoother_first_tool": smoother.tolist(),
            "contact_flagged_fraction": float(np.mean(flags[pressing] & BIT["contact"] != 0)),
            "contact_absorbed_n": absorbed,
            "compensated_rms_over_noise": (np.sqrt(np.mean(compensated[quiet] ** 2, axis=0)) / noise).tolist(),
            "false_contact_fraction": float(np.mean(flags[quiet] & BIT["contact"] != 0))}


def format_live_tables(summary: dict) -> str:
    """The summary as text."""
    def row(label, values, fmt="{:9.4f}"):
        return f"{label:<38}" + "".join(fmt.format(v) for v in values)

    lines = [f"{'bias error, RMS (N, N·m)':<38}" + "".join(f"{a:>9}" for a in AXES),
             row("live tracker", summary["bias_rms_online"]),
             row("no tracking (held at the first tare)", summary["bias_rms_untracked"]),
             row("live, first tool only", summary["bias_rms_online_first_tool"]),
             row("offline smoother, first tool only", summary["bias_rms_smoother_first_tool"]),
             row("compensated RMS / noise (static)", summary["compensated_rms_over_noise"], "{:9.2f}"),
             "",
             f"10 N contact held 5 s: {100 * summary['contact_flagged_fraction']:.1f} % of its samples flagged; the "
             f"bias moved {summary['contact_absorbed_n']:+.3f} N more than the true bias did",
             f"static, contact-free samples flagged as contact by chance: "
             f"{100 * summary['false_contact_fraction']:.2f} % (gate at the 0.999 chi-square quantile)",
             "tools identified offline: " + ", ".join(
                 f"{n} {t['mass']:.3f} ± {t['mass_stderr']:.3f} kg (true {summary['true_mass'][n]:g})"
                 for n, t in summary["tools"].items()),
             f"replay: {summary['n_samples']} samples at {summary['replay_samples_per_s']:,.0f} samples/s "
             f"({summary['replay_cpu_s']:.2f} s CPU, {summary['replay_wall_s']:.2f} s wall)"]
    return "\n".join(lines)
