"""iCub strain-board matrix file: hand-computed Q1.15 entries and full scales, refusals."""

from __future__ import annotations

import numpy as np
import pytest

from ftcal.core.conversion import from_raw
from ftcal.files.firmware import firmware_filename, firmware_matrix, write_firmware_matrix
from ftcal.files.model_files import save_model
from ftcal.runtime.errors import FtcalError, FtcalWarning

CHANNELS = ["s1", "s2", "s3", "s4", "s5", "s6"]
OUTPUTS = ["Fx", "Fy", "Fz", "Tx", "Ty", "Tz"]

# Row Fx = [0.01, −0.002, 0, 0, 0, 0.003] N/count; rows Fy..Tz = 0.5 on the diagonal.
C = np.diag([0.0, 0.5, 0.5, 0.5, 0.5, 0.5])
C[0] = [0.01, -0.002, 0, 0, 0, 0.003]


def affine_model(matrix, offset=np.zeros(6), extra_inputs=()):
    """Degree-1 model y = matrix · u + offset, with optional later inputs given zero weight."""
    raw = np.vstack([matrix.T, np.zeros((len(extra_inputs), 6)), offset])
    return from_raw(raw, degree=1, input_names=CHANNELS + list(extra_inputs), output_names=OUTPUTS)


def test_hand_computed_matrix_file(tmp_path):
    # Fx: Σ|C| = 0.015, FS = ceil(32767 · 0.015) = ceil(491.505) = 492;
    #   0.01 · 32767/492 · 32768 = 21823.35 → 21823 = 0x553F
    #  −0.002 · 32767/492 · 32768 = −4364.67 → −4365 → 65536 − 4365 = 61171 = 0xEEF3
    #   0.003 · 32767/492 · 32768 = 6547.01 → 6547 = 0x1993
    # Fy..Tz: FS = ceil(32767 · 0.5) = 16384; 0.5 · 32767/16384 · 32768 = 32767 = 0x7FFF.
    path = tmp_path / firmware_filename("SN042")
    write_firmware_matrix(affine_model(C), path)
    assert path.name == "matrix_SN042.txt"
    data = path.read_bytes()
    lines = data.split(b"\r\n")
    assert lines[-1] == b"" and len(lines) == 44 and b"\n" not in data.replace(b"\r\n", b"")
    expected = [["553F", "EEF3", "0000", "0000", "0000", "1993"]]
    expected += [["7FFF" if j == i else "0000" for j in range(6)] for i in range(1, 6)]
    assert [line.decode() for line in lines[:36]] == [v for row in expected for v in row]
    assert lines[36] == b"1"
    assert [int(v) for v in lines[37:43]] == [492, 16384, 16384, 16384, 16384, 16384]


def test_board_reproduces_the_model_within_quantization():
    fm = firmware_matrix(affine_model(C))
    # One Q1.15 step is FS/32767/32768 per count; rounding costs at most half of it.
    bound = fm.full_scale[:, None] / 32767 / 32768 / 2
    assert np.all(np.abs(fm.effective_matrix() - C) <= bound + 1e-18)


def test_rounding_to_plus_one_raises_the_full_scale():
    # 32767 · c = 39999.5 gives FS = 40000 and Cs · 32768 = 32767.59, which rounds to 32768,
    # outside Q1.15; FS = 40001 gives 39999.5/40001 · 32768 = 32766.77 → 32767.
    matrix = np.eye(6) * 0.5
    matrix[0, 0] = 39999.5 / 32767
    fm = firmware_matrix(affine_model(matrix))
    assert fm.full_scale[0] == 40001 and fm.q15[0, 0] == 32767


def test_offset_is_not_representable_and_warns():
    with pytest.warns(FtcalWarning, match=r"no offset term.*2\.5 on 'Fz'"):
        firmware_matrix(affine_model(C, offset=np.array([0, 0, 2.5, 0, 0, 0.1])))


def test_zero_weight_temperature_input_is_accepted():
    fm = firmware_matrix(affine_model(C, extra_inputs=["T"]))
    assert fm.full_scale[0] == 492


def test_refuses_temperature_and_higher_degree_terms():
    raw = np.vstack([C.T, np.full((1, 6), 0.01), np.zeros((1, 6))])
    with_temperature = from_raw(raw, degree=1, input_names=CHANNELS + ["T"], output_names=OUTPUTS)
    with pytest.raises(FtcalError, match=r"affine map of the inputs s1, .*, s6; this model's term 'T'"):
        firmware_matrix(with_temperature)
    quadratic = from_raw(np.vstack([C.T, np.zeros((21, 6)), np.zeros((1, 6))]), degree=2,
                         input_names=CHANNELS, output_names=OUTPUTS)
    quadratic.coef_[6 + 3, 2] = 1e-9  # s1·s4
    with pytest.raises(FtcalError, match=r"term 's1·s4' has nonzero coefficients"):
        firmware_matrix(quadratic)
    degree_two_but_affine = from_raw(np.vstack([C.T, np.zeros((22, 6))]), degree=2,
                                     input_names=CHANNELS, output_names=OUTPUTS)
    assert firmware_matrix(degree_two_but_affine).full_scale[0] == 492


def test_refuses_wrong_shapes_and_infeasible_gains(tmp_path):
    five = from_raw(np.ones((6, 6)), degree=1, input_names=CHANNELS[:5], output_names=OUTPUTS)
    with pytest.raises(FtcalError, match="6 raw channels to 6 wrench components; this model has 5 inputs"):
        firmware_matrix(five)
    # Σ|C| = 6 per row needs FS = 196602 > 65535.
    with pytest.raises(FtcalError, match="needs full scale 196602, above the board's 16-bit limit 65535"):
        firmware_matrix(affine_model(np.ones((6, 6))))
    zero_row = C.copy()
    zero_row[3] = 0
    with pytest.raises(FtcalError, match="'Tx' does not depend on any raw channel"):
        firmware_matrix(affine_model(zero_row))


def test_write_model_names_the_file_in_a_directory(tmp_path):
    written = save_model(affine_model(C), tmp_path, "icub-firmware", serial="SN7")
    assert written == tmp_path / "matrix_SN7.txt" and written.exists()
    with pytest.raises(FtcalError, match="give the sensor serial number"):
        save_model(affine_model(C), tmp_path, "icub-firmware")


def test_inputs_that_are_not_adc_counts_are_refused_with_what_to_fit():
    model = affine_model(C)
    with pytest.raises(FtcalError, match=r"in other units \(s1 \[N\].*Fit a degree-1 model on the six raw ADC-count"):
        firmware_matrix(model, input_units=["N"] * 6)
    firmware_matrix(model, input_units=["counts"] * 6)  # declared counts pass
    model.input_range_ = np.tile([-40000.0, 100.0], (6, 1))
    with pytest.raises(FtcalError, match=r"in \[-32768, 32767\]; this model was trained on s1 \[-40000, 100\]"):
        firmware_matrix(model)
