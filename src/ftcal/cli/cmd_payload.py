"""``ftcal payload``: identify the sensor bias and the tool's mass, centre of mass (and inertia)."""

from __future__ import annotations

import argparse

from ..core.limits import BIAS_DRIFTS
from ..runtime.errors import FtcalError
from ._common import column_list, positive_float, require_suffix
from ._examples import epilog
from ._gravity import add_kinematics_options, add_robot_source_options, check_not_input, kinematics_source

MAX_GROUPS_PRINTED = 8
# A re-tared bias further than this many standard errors from the identified one is drift, not noise.
REBIAS_SIGNIFICANT = 3.0


def register(sub) -> None:
    p = sub.add_parser("payload", **epilog("payload"), help="identify the sensor bias and the tool's mass and centre of mass",
                       description="Identify, by linear least squares, the F/T sensor's force and torque bias "
                                   "and the attached tool's mass and centre of mass (sensor frame) from static "
                                   "poses; --dynamic adds the inertia from angular velocity/acceleration and "
                                   "linear acceleration. Sign convention: the sensor reads the wrench the tool "
                                   "applies on it (a mass m at rest adds m·g); use --reaction for sensors that "
                                   "report the opposite sign.")
    p.add_argument("data", nargs="+", metavar="DATA", help="CSV or Parquet files, one row per sample")
    p.add_argument("-o", "--output", required=True, metavar="PAYLOAD.json",
                   help="payload file: mass (kg), com (m), force/torque bias (N, N·m), inertia with --dynamic, "
                        "standard errors; for 'ftcal compensate' and 'ftcal convert --to ros-yaml|ft-tools-ros2'")
    p.add_argument("--wrench", type=column_list, default=("u1", "u2", "u3", "u4", "u5", "u6"),
                   metavar="FX,FY,FZ,TX,TY,TZ",
                   help="measured wrench columns, N and N·m (default u1,...,u6)")
    add_kinematics_options(p)
    add_robot_source_options(p)
    p.add_argument("--group-by", metavar="COL",
                   help="column naming the cross-validation groups, e.g. the pose (default: one per file)")
    p.add_argument("--keep-moving", action="store_true",
                   help="static model: use every sample (default: only the static holds, found from the orientation, "
                        "joints or gravity over --time, else the table's static column from ftcal dataset; the moving "
                        "samples are counted and excluded)")
    p.add_argument("--reaction", action="store_true",
                   help="the sensor reports the wrench it applies on the tool (opposite sign): negate readings")
    p.add_argument("--frame", metavar="NAME", help="name of the sensor frame, stored in the file (e.g. ft_sensor)")
    drift = p.add_argument_group("a bias that drifts (needs --time for the time models)")
    drift.add_argument("--bias-drift", choices=BIAS_DRIFTS, default="auto",
                       help="bias over the recording: constant, affine in time, a random walk (state-space model), "
                            "or auto: chosen by BIC, the simpler model unless the evidence is strong (default "
                            "auto; without --time the bias is constant)")
    drift.add_argument("--temperature", metavar="COL", help="the bias is also affine in this temperature column")
    drift.add_argument("--rebias", metavar="PAYLOAD.json",
                       help="re-tare: re-estimate only the bias from DATA with this file's mass and centre of mass "
                            "fixed, report the drift since identification, write the updated file to -o")
    p.set_defaults(func=run)


def run(args) -> int:
    import sys
    import warnings

    from ..check.conventions import ConventionWarning, HoldCollector, payload_warning
    from ..files.payload_json import save_payload
    from ..payload.identify import check_mass_sign
    from ..payload.parameters import PayloadParameters
    from ..payload.tables import group_statistics, identify_recording, read_payload_tables
    from ._holds import StaticRows, payload_excitation

    require_suffix(args.output, (".json",), "-o")
    check_not_input(args.output, args.data + ([args.rebias] if args.rebias else []))
    if args.rebias:
        return run_rebias(args)
    if args.time is None and args.bias_drift in ("linear", "random-walk"):
        from ..data.table_chunks import table_has_columns

        # As --time's help says: the column 'time' where every table has one.
        if not all(table_has_columns(path, ["time"]) for path in args.data):
            raise FtcalError(f"--bias-drift {args.bias_drift} needs the time column and {', '.join(args.data)} "
                             "has none named 'time': give --time COL.")
        args.time = "time"
    if args.dynamic and args.bias_drift in ("linear", "random-walk"):
        raise FtcalError(f"--bias-drift {args.bias_drift} works with static poses only; leave out --dynamic "
                         "or use --bias-drift none.")
    source = kinematics_source(args)
    static = None if args.dynamic or args.keep_moving else StaticRows(args, source)
    # The convention check's holds are taken from the tables as the fit reads them (one read).
    holds = HoldCollector(source, static, wrench=args.wrench, reaction=args.reaction, time=args.time)
    recording = read_payload_tables(args.data, source, wrench=args.wrench, group_by=args.group_by,
                                    reaction=args.reaction, time=args.time, temperature=args.temperature,
                                    select=holds)
    for line in () if static is None else static.notes:
        print(f"static samples: {line}")
    result = identify_recording(recording, bias_drift=args.bias_drift, dynamic=args.dynamic,
                                time_column=args.time, temperature_column=args.temperature)
    fit = result.fit
    message = payload_warning(args.data, source, fit, args.g, wrench=args.wrench, reaction=args.reaction,
                              time=args.time, holds=holds)
    if message:  # the fit looks like a sign/frame/zeroing mistake: ftcal check's tests on the static holds
        warnings.warn(message, ConventionWarning, stacklevel=1)
    check_mass_sign(fit)
    print_fit(fit, result.n_groups, args)
    print_drift(result)
    print(payload_excitation(group_statistics(recording, dynamic=args.dynamic)))
    payload = PayloadParameters.from_fit(fit, gravity=args.g, frame=args.frame, reaction=args.reaction,
                                         wrench_columns=tuple(args.wrench), drift=result.drift)
    save_payload(payload, args.output, sources=args.data)
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


def print_drift(result) -> None:
    """What drift was found, and how much modelling it moved mass and centre of mass."""
    drift = result.drift
    if drift is None:
        return
    if result.selection:
        print(f"bias model: {drift.model} ({result.selection})")
    else:
        print(f"bias model: {drift.model}")
    if drift.temperature_coefficients is not None:
        print(f"  bias per unit of {drift.temperature_column}: " + _axes(drift.temperature_coefficients))
    if result.change is None:
        if result.verdict():
            print(result.verdict())
        return
    hours = max(result.hours, 1e-300)
    print(f"  bias change over the recording ({result.hours * 60:.3g} min): " + _axes(result.change))
    print("  drift rate: " + _axes(result.change / hours, "/h"))
    if result.walk_std is not None:
        print("  random-walk std: " + _axes(result.walk_std, "/√h"))
    fit, constant = result.fit, result.constant
    dm = fit.mass - constant.mass
    dc = 1000.0 * (fit.com - constant.com)
    print(f"  vs a constant bias: mass {dm:+.4g} kg ({dm / max(constant.stderr['mass'], 1e-300):+.2g} of its standard "
          f"error, {100 * dm / constant.mass:+.2g} %), centre of mass "
          + " ".join(f"{a} {v:+.3g}" for a, v in zip("xyz", dc)) + " mm")
    verdict = result.verdict()
    if verdict:
        print(verdict)


def _axes(values, per: str = "") -> str:
    units = ("N", "N", "N", "N·m", "N·m", "N·m")
    return "  ".join(f"{a} {v:+.4g} {u}{per}" for a, v, u in zip(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), values, units))


def identified_bias(payload, time):
    """The payload file's bias to compare a re-tare with, shape (6,): its trajectory averaged over ``time``
    when it drifts in time (so its own recording is compared like for like), else its constant bias."""
    import numpy as np

    drift = payload.drift
    if drift is None or drift.knot_times is None or time is None:
        return payload.bias
    return np.array([np.interp(time, drift.knot_times, drift.knot_bias[:, j]).mean() for j in range(6)])


def run_rebias(args) -> int:
    """Re-tare: the bias alone from new data, mass and centre of mass from the payload file."""
    import sys
    from dataclasses import replace

    import numpy as np

    from ..files.payload_json import load_payload, save_payload
    from ..payload.drift import BiasDrift
    from ..payload.tables import read_payload_tables, rebias

    payload = load_payload(args.rebias)
    if args.reaction != payload.reaction:
        raise FtcalError(f"--reaction: {args.rebias} was identified {'with' if payload.reaction else 'without'} "
                         "--reaction; give the same sign convention.")
    from ._holds import StaticRows

    # Options that change nothing in a re-tare are refused rather than silently ignored.
    for option, given in (("--dynamic", args.dynamic), ("--bias-drift", args.bias_drift != "auto"),
                          ("--group-by", args.group_by is not None), ("--frame", args.frame is not None)):
        if given:
            raise FtcalError(f"{option} does not apply to --rebias (the re-tare keeps {args.rebias}'s model and "
                             "estimates one constant bias); leave it out.")
    temperature = payload.drift.temperature_column if payload.needs_temperature else None
    if args.temperature is not None and args.temperature != temperature:
        raise FtcalError(f"--temperature {args.temperature}: {args.rebias} has "
                         + (f"its temperature term on column {temperature!r}" if temperature else "no temperature term")
                         + "; --rebias uses the file's; leave it out.")
    source = kinematics_source(args)
    # Like the identification: only the still samples (moving ones carry inertial forces the model lacks).
    static = None if args.keep_moving else StaticRows(args, source)
    recording = read_payload_tables(args.data, source, wrench=args.wrench, reaction=payload.reaction,
                                    time=args.time, temperature=temperature, select=static)
    for line in () if static is None else static.notes:
        print(f"static samples: {line}")
    found = rebias(recording, payload)
    old = identified_bias(payload, recording.time)
    old_se = np.r_[payload.stderr["force_bias"], payload.stderr["torque_bias"]]
    change = found.bias - old
    z = change / np.sqrt(found.stderr ** 2 + old_se ** 2)
    print(f"bias re-estimated from {recording.n_samples} samples with mass {payload.mass:.6g} kg and the centre "
          f"of mass of {args.rebias} held fixed ({found.stderr_kind})")
    for a, new, se, d, zi in zip(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), found.bias, found.stderr, change, z):
        unit = "N" if a[0] == "F" else "N·m"
        if np.isnan(zi):  # undetermined at identification: the value follows the file's convention
            print(f"  {a + ' bias':<10}{new:>12.6g} {unit}   undetermined by the identification poses "
                  f"(consistent with {args.rebias}'s convention; change {d:+.4g} {unit} not comparable)")
            continue
        print(f"  {a + ' bias':<10}{new:>12.6g} ± {se:.2g} {unit}   change since identification {d:+.4g} {unit} "
              f"({zi:+.1f} standard errors)")
    end = payload.drift.time_end if payload.drift is not None else None
    if recording.time is not None and end is not None and recording.time[0] > end:
        hours = (float(np.mean(recording.time)) - end) / 3600.0
        print(f"  drift rate since identification ({hours:.3g} h): " + _axes(change / hours, "/h"))
    else:
        print("  drift rate: unknown (needs --time, and a payload file whose recording ended before this one)")
    beyond = [a for a, zi in zip(("Fx", "Fy", "Fz", "Tx", "Ty", "Tz"), z) if abs(zi) > REBIAS_SIGNIFICANT]
    if beyond:
        print(f"  the bias moved more than the identification's uncertainty explains ({REBIAS_SIGNIFICANT:g} standard "
              f"errors) on {', '.join(beyond)}: the sensor drifted; compensate with the new file")
    else:
        print("  the change is within what the identification's uncertainty explains")
    t = recording.time
    drift = BiasDrift("none", args.time if t is not None else None, None if t is None else float(t[0]),
                      None if t is None else float(t[-1]),
                      temperature_column=temperature,
                      temperature_reference=payload.drift.temperature_reference if temperature else None,
                      temperature_coefficients=payload.drift.temperature_coefficients if temperature else None,
                      selection=f"re-tared from {', '.join(map(str, args.data))}")
    new_se = np.where(np.isnan(old_se), np.nan, found.stderr)  # still undetermined where it was
    stderr = dict(payload.stderr, force_bias=new_se[:3], torque_bias=new_se[3:])
    updated = replace(payload, force_bias=found.bias[:3], torque_bias=found.bias[3:], stderr=stderr, drift=drift)
    save_payload(updated, args.output, sources=[args.rebias, *args.data])
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


def print_fit(fit, n_groups: int, args) -> None:
    import numpy as np

    from ..payload.identify import AXES

    unit = {"mass": "kg", "com": "m", "force_bias": "N", "torque_bias": "N·m", "inertia": "kg·m²"}
    kind = "dynamic (inertia included)" if fit.dynamic else "static"
    print(f"payload from {fit.n_samples} samples in {n_groups} group(s), {kind} model, "
          f"gravity {args.g:g} m/s²")
    def line(name, value, se, unit_name):
        if np.isnan(se):  # the poses do not determine it: the file holds a convention, not an estimate
            return f"  {name:<14}{'undetermined':>14} (file: {value:.6g} {unit_name} by convention)"
        return f"  {name:<14}{value:>14.6g} ± {se:.2g} {unit_name}"

    print(line("mass", fit.mass, fit.stderr["mass"], unit["mass"]))
    for key in ("com", "force_bias", "torque_bias"):
        for axis, value, se in zip("xyz", getattr(fit, key), fit.stderr[key]):
            print(line(key.replace("_", " ") + " " + axis, value, se, unit[key]))
    if fit.dynamic:
        for (i, j) in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)):
            name = "I" + "xyz"[i] + "xyz"[j] + " (com)"
            print(line(name, fit.inertia[i, j], fit.stderr["inertia"][i, j], unit["inertia"]))
    if fit.undetermined is not None:
        print(f"undetermined: {fit.undetermined.message}")
    print("residual RMS: " + "  ".join(f"{a} {v:.4g}" for a, v in zip(AXES, fit.residual_rms)) + "  (N, N·m)")
    if fit.cross_validation:
        scored = [g for g in fit.cross_validation if g.rms is not None]
        if scored:
            pooled = np.sqrt(sum(g.n_samples * g.rms ** 2 for g in scored) / sum(g.n_samples for g in scored))
            print("cross-validated residual RMS (each group left out of the fit in turn): "
                  + "  ".join(f"{a} {v:.4g}" for a, v in zip(AXES, pooled)))
        # The groups that fit worst when left out come first: they are the suspicious poses.
        with np.errstate(over="ignore"):  # an axis fitted exactly (residual 0) ranks its groups first: inf
            ranked = sorted(fit.cross_validation, key=lambda g: -np.inf if g.rms is None else -float(
                np.sum((g.rms / np.maximum(fit.residual_rms, 1e-300)) ** 2)))
        for g in ranked[:MAX_GROUPS_PRINTED]:
            text = ("not identifiable without this group" if g.rms is None
                    else "  ".join(f"{a} {v:.4g}" for a, v in zip(AXES, g.rms)))
            print(f"  {g.group} ({g.n_samples} samples): {text}")
        if len(ranked) > MAX_GROUPS_PRINTED:
            print(f"  ... {len(ranked) - MAX_GROUPS_PRINTED} more group(s) fit better")
    else:
        print("cross-validation: one group only (give several files or --group-by COL)")
    print(f"weighting: {fit.weighting} ({fit.weighting_evidence}); standard errors: {fit.stderr_kind}")
    print(f"condition number of the weighted regressor: {fit.condition_number:.3g}"
          + ("" if not fit.poorly_excited else f"; poorly excited: {', '.join(fit.poorly_excited)}"))
