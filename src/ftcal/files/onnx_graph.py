"""ONNX graphs of static models (``ftcal convert MODEL --to onnx``), for onnxruntime users (ROS 2, C++).

The graph takes ``u`` (float64, [N, n_inputs], the model's input order) and
returns ``y`` (float64, [N, n_outputs]). It evaluates like
:meth:`ftcal.core.model.CalibrationModel.predict`: normalized inputs
``x = (u − offset) · (1 / scale)``; the degree-p monomials whose first factor
is ``x_i`` are ``x_i`` times a contiguous tail of the degree-(p−1) block (the
folded product of :class:`ftcal.core.features.MonomialEvaluator`, one multiply per
term); then one MatMul with the normalized-basis coefficients plus the offset
row. Opset :data:`OPSET` and IR version :data:`IR_VERSION` load in every
onnxruntime since 1.14 (``pyproject.toml`` asks for ≥ 1.18).

ARX models have state (past outputs), which a stateless graph cannot carry;
they are refused with a pointer to ``--to c``.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from ..core.features import n_monomials
from ..core.model import CalibrationModel
from ..runtime.atomic import write_with
from ..runtime.errors import FtcalError, ParameterError
from .c_code import check_finite
from .c_text import described
from .model_json import ModelFile, ftcal_version
from .targets import ConvertOptions, Written

OPSET = 17
IR_VERSION = 8
INPUT, OUTPUT = "u", "y"


def build_onnx(model: CalibrationModel, *, sha256: str | None = None, input_units=None, output_units=None):
    """The checked ``onnx.ModelProto`` of a static ``model``.

    Parameters
    ----------
    model : fitted static CalibrationModel
    sha256 : digest of the model file, stored in the graph's metadata
    input_units, output_units : sequences of str or None, stored in the metadata

    Returns
    -------
    onnx.ModelProto

    Raises
    ------
    FtcalError
        ARX models, non-finite coefficients.
    """
    from onnx import helper, numpy_helper

    model._check_fitted()
    layout = model.layout_
    if not layout.is_static:
        raise ParameterError('to', f"{{to}} onnx takes static models; this one is ARX (na={layout.na}, nb={layout.nb}), "
                         "whose free run needs state between samples: use {to} c (NAME_init / NAME_step).")
    check_finite(model)
    nu = len(model.input_names_)
    degree = layout.basis.degree
    inn = model.input_normalization_
    nodes, initializers = [], []

    def constant(name: str, value) -> str:
        initializers.append(numpy_helper.from_array(np.asarray(value), name))
        return name

    def node(op: str, inputs: list[str], output: str, **attributes) -> str:
        nodes.append(helper.make_node(op, inputs, [output], name=output, **attributes))
        return output

    centered = node("Sub", [INPUT, constant("input_offset", inn.offset.astype(np.float64))], "centered")
    x = node("Mul", [centered, constant("input_inv_scale", 1.0 / inn.scale)], "x")
    axis = constant("axis_1", np.array([1], dtype=np.int64))
    columns = [node("Slice", [x, constant(f"start_{i}", np.array([i], dtype=np.int64)),
                              constant(f"stop_{i}", np.array([i + 1], dtype=np.int64)), axis], f"x_{i}")
               for i in range(nu)]
    blocks, previous = [x], x
    for p in range(2, degree + 1):
        size = n_monomials(nu, p - 1)
        parts = []
        for i in range(nu):
            count = n_monomials(nu - i, p - 1)
            tail = node("Slice", [previous, constant(f"tail_start_{p}_{i}", np.array([size - count], dtype=np.int64)),
                                  constant(f"tail_stop_{p}_{i}", np.array([size], dtype=np.int64)), axis],
                        f"tail_{p}_{i}")
            parts.append(node("Mul", [tail, columns[i]], f"monomials_{p}_{i}"))
        previous = node("Concat", parts, f"degree_{p}", axis=1) if len(parts) > 1 else parts[0]
        blocks.append(previous)
    features = node("Concat", blocks, "monomials", axis=1) if len(blocks) > 1 else x
    product = node("MatMul", [features, constant("coefficients", np.ascontiguousarray(model.coef_[:-1]))], "product")
    node("Add", [product, constant("offset", np.ascontiguousarray(model.coef_[-1]))], OUTPUT)
    return checked_onnx(nodes, initializers, model, f"degree {degree}", sha256, input_units, output_units)


def checked_onnx(nodes, initializers, model, kind: str, sha256: str | None, input_units, output_units):
    """The checked ``onnx.ModelProto`` of graph ``nodes`` (``u`` float64 [N, n_inputs] -> ``y``) of any family:
    producer, IR version, ``kind`` in its doc string, and the metadata block (inputs and outputs with units,
    the model file's sha256)."""
    import onnx
    from onnx import TensorProto, helper

    nu, ny = len(model.input_names_), len(model.output_names_)
    graph = helper.make_graph(
        nodes, "ftcal_model",
        [helper.make_tensor_value_info(INPUT, TensorProto.DOUBLE, ["N", nu])],
        [helper.make_tensor_value_info(OUTPUT, TensorProto.DOUBLE, ["N", ny])],
        initializers)
    onnx_model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)],
                                   producer_name="ftcal", producer_version=ftcal_version(),
                                   doc_string=f"ftcal calibration model, {kind}: u -> y")
    onnx_model.ir_version = IR_VERSION
    metadata = {"inputs": described(model.input_names_, input_units, ","),
                "outputs": described(model.output_names_, output_units, ",")}
    if sha256:
        metadata["model_sha256"] = sha256
    helper.set_model_props(onnx_model, metadata)
    onnx.checker.check_model(onnx_model, full_check=True)
    return onnx_model


def write_onnx(source: ModelFile, output: Path, options: ConvertOptions) -> Written:
    """Registry writer: the graph of ``source.model`` to ``output`` (``.onnx``)."""
    sha256 = hashlib.sha256(options.input_path.read_bytes()).hexdigest()
    graph = build_onnx(source.model, sha256=sha256, input_units=source.input_units,
                       output_units=source.output_units)
    write_with(output, lambda tmp: tmp.write_bytes(graph.SerializeToString()))
    return Written((output,))
