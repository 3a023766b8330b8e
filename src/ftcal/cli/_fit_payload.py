"""``ftcal fit --estimate-payload LINK``: estimate an unknown payload, then fit the calibration to the completed wrench."""

from __future__ import annotations

import sys


def check_payload_options(args) -> None:
    """Refuse option combinations before any data is read."""
    from ..runtime.errors import FtcalError

    if args.payload_mass is not None and args.estimate_payload is None:
        raise FtcalError("--payload-mass goes with --estimate-payload LINK.")


def read_with_payload(args, inputs, outputs):
    """The dataset with the payload's wrench added to the outputs; prints the payload estimate.

    Reads the ``Y_<LINK>_<output>_<parameter>`` columns written by
    ``ftcal dataset --estimate-payload LINK`` (4 static or 10 parameters).
    """
    from dataclasses import replace

    from ..data.tables import read_dataset, read_table
    from ..payload.regressor import INERTIAL_PARAMETERS
    from ..payload.unknown_load import estimate_payload, payload_column
    from ..runtime.errors import FtcalError

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
    known = data.outputs[:, :len(outputs)]
    regressor = data.outputs[:, len(outputs):].reshape(data.n_samples, len(outputs), k)
    data = replace(data, outputs=known, output_names=tuple(outputs))
    estimate = estimate_payload(data, regressor, link, payload_mass=args.payload_mass)
    print("\n".join(estimate.lines()))
    return replace(data, outputs=known + regressor @ estimate.values)
