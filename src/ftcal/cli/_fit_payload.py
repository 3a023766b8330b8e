"""``ftcal fit --estimate-payload LINK``: the calibration and an unknown payload fitted together."""

from __future__ import annotations

import sys


def check_payload_options(args) -> None:
    """Refuse options the joint calibration + payload fit does not support, before reading data."""
    from ..errors import FtcalError

    if args.payload_mass is not None and args.estimate_payload is None:
        raise FtcalError("--payload-mass goes with --estimate-payload LINK.")
    if args.estimate_payload is None:
        return
    unsupported = [flag for flag, used in (("--degree auto", args.degree == "auto"), ("--lasso", args.lasso),
                                           ("--ridge", args.ridge), ("--solver osqp", args.solver == "osqp"),
                                           ("--na", args.na), ("--nb", args.nb)) if used]
    if unsupported:
        raise FtcalError(f"--estimate-payload fits a static least-squares model; drop {', '.join(unsupported)}.")


def run_with_payload(args, inputs, outputs) -> int:
    """Read the data with the payload regressor columns, fit both, write the model, report the payload."""
    from dataclasses import replace

    from ..errors import FtcalError
    from ..io.model_json import save_model
    from ..io.tables import read_dataset, read_table
    from ..payload.regressor import INERTIAL_PARAMETERS
    from ..unknown_load import fit_with_payload, payload_column
    from .cmd_fit import report_fit

    link = args.estimate_payload
    header = set(read_table(args.data[0]).columns)
    k = len(INERTIAL_PARAMETERS) if payload_column(link, outputs[0], "Ixx") in header else 4
    columns = tuple(payload_column(link, o, p) for o in outputs for p in INERTIAL_PARAMETERS[:k])
    missing = [c for c in columns if c not in header]
    if missing:
        raise FtcalError(f"{args.data[0]}: no column {missing[0]!r}; write the dataset with "
                         f"'ftcal dataset ... --estimate-payload {link}'.")
    data = read_dataset(args.data, inputs, (*outputs, *columns), segment_by=args.segment_by, group_by=args.group_by)
    print(f"read {data.n_samples} samples from {len(args.data)} file(s): inputs {','.join(inputs)} "
          f"-> outputs {','.join(outputs)} + payload on {link} ({k} parameters)", file=sys.stderr)
    regressor = data.outputs[:, len(outputs):].reshape(data.n_samples, len(outputs), k)
    known = replace(data, outputs=data.outputs[:, :len(outputs)], output_names=tuple(outputs))
    model, estimate = fit_with_payload(known, regressor, link, degree=args.degree,
                                       normalization=args.normalization, payload_mass=args.payload_mass)
    save_model(model, args.output, sources=[str(p) for p in args.data])
    print("\n".join(estimate.lines()))
    report_fit(model, args.output)
    return 0
