"""ONNX graphs run by onnxruntime against CalibrationModel.predict."""

from __future__ import annotations

import hashlib

import numpy as np
import onnx
import onnxruntime as ort
import pytest
from test_export_c import assert_relative, sensor_data

from ftcal.cli import main
from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.core.solvers import Lasso
from ftcal.files.model_files import save_model
from ftcal.files.onnx_graph import OPSET, build_onnx
from ftcal.runtime.errors import FtcalError


def run_onnx(proto, u):
    session = ort.InferenceSession(proto.SerializeToString(), providers=["CPUExecutionProvider"])
    return session.run(["y"], {"u": u})[0]


@pytest.mark.parametrize("degree, lam", [(1, None), (2, None), (3, None), (4, None), (5, None), (4, 30.0)])
def test_onnxruntime_matches_predict(degree, lam):
    u, y = sensor_data(1000, seed=degree)
    solver = Lasso(lam) if lam else None
    model = CalibrationModel(degree, solver=solver).fit(u, y)
    u_test, _ = sensor_data(400, seed=50 + degree)
    out = run_onnx(build_onnx(model), u_test)
    assert out.dtype == np.float64 and out.shape == (400, 6)
    assert_relative(out, model.predict(u_test, warn_out_of_range=False))


def test_cli_writes_a_checked_graph(tmp_path, capsys):
    u, y = sensor_data(600)
    path = tmp_path / "m.json"
    save_model(CalibrationModel(3).fit(u, y), path, input_units=["count"] * 6 + ["degC"])
    out = tmp_path / "model.onnx"
    assert main(["convert", str(path), "--to", "onnx", "-o", str(out)]) == 0
    proto = onnx.load(str(out))
    onnx.checker.check_model(proto, full_check=True)
    assert [o.version for o in proto.opset_import if o.domain in ("", "ai.onnx")] == [OPSET]
    assert [i.name for i in proto.graph.input] == ["u"] and [o.name for o in proto.graph.output] == ["y"]
    assert proto.graph.input[0].type.tensor_type.elem_type == onnx.TensorProto.DOUBLE
    props = {p.key: p.value for p in proto.metadata_props}
    assert props["model_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert props["inputs"].startswith("u1 [count],")
    u_test, _ = sensor_data(50, seed=3)
    model = CalibrationModel(3).fit(u, y)
    assert_relative(run_onnx(proto, u_test), model.predict(u_test, warn_out_of_range=False))


def test_arx_is_refused_with_a_pointer_to_c(tmp_path, capsys):
    u, y = sensor_data(600)
    data = Dataset.from_arrays(u, y)
    path = tmp_path / "arx.json"
    save_model(CalibrationModel(1, na=1).fit(data), path)
    with pytest.raises(FtcalError, match="use to c"):
        build_onnx(CalibrationModel(1, na=1).fit(data))
    assert main(["convert", str(path), "--to", "onnx", "-o", str(tmp_path / "m.onnx")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "use --to c" in err[0]
    assert main(["convert", str(path), "--to", "onnx", "-o", str(tmp_path / "m.bin")]) == 2
    assert "must end in .onnx" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["arx.json"]
