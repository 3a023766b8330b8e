"""The paper's XML: reading hand-written files, row order, round trips, rejected files."""

from __future__ import annotations

import re

import numpy as np
import pytest

from ftcal.core.conversion import from_raw, to_raw
from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel, model_from_fitted
from ftcal.core.normalization import Normalization
from ftcal.files.paper_xml import parse_paper_xml, read_paper_xml, write_paper_xml
from ftcal.runtime.errors import FtcalError, PrecisionLossWarning

# Like the docs/formats.md §1 example (np=1, nu=7, ny=6: 8 rows), with uneven white space and
# several float spellings.
HAND_WRITTEN = """<?xml version="1.0" encoding="utf-8"?>
<group name="modelClassParams">
   <param name="np">1</param>
   <param name="ny"> 6 </param>
   <param name="nu">7</param>
   <param name="na">0</param>
   <param name="nb">0</param>
   <param name="string">1st_degree</param>
   <param name="row1">(1  0  0  0  0  0)</param>
   <param name="row2">( 0 2 0 0 0 0 )</param>
   <param name="row3">(0\t0\t3.0\t0\t0\t0)</param>
   <param name="row4">(0 0 0
       1e-3 0 0)</param>
   <param name="row5">(0  0  0  0  -.5  0)</param>
   <param name="row6">(0  0  0  0  0  +2.)</param>
   <param name="row7">(0.1  0.1  0.1  0.1  0.1  1.5D-01)</param>
   <param name="row8">(90.7  49.0  -256.9  -6.6  -1.5  -3.7)</param>
</group>
"""


def test_reads_the_formats_example_and_predicts_by_hand():
    model = parse_paper_xml(HAND_WRITTEN, "hand.xml")
    assert model.input_names_ == ("u1", "u2", "u3", "u4", "u5", "u6", "T")
    assert model.output_names_ == ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")
    # u = (1, 2, 3, 4, 5, 6), T = 30:
    #   Fx = 1·1 + 0.1·30 + 90.7 = 94.7      Fy = 2·2 + 3 + 49.0 = 56
    #   Fz = 3·3 + 3 − 256.9 = −244.9        Tx = 1e-3·4 + 3 − 6.6 = −3.596
    #   Ty = −0.5·5 + 3 − 1.5 = −1.0         Tz = 2·6 + 0.15·30 − 3.7 = 12.8
    prediction = model.predict(np.array([[1, 2, 3, 4, 5, 6, 30.0]]))
    np.testing.assert_allclose(prediction[0], [94.7, 56.0, -244.9, -3.596, -1.0, 12.8], rtol=1e-12)


def test_hand_written_file_is_an_affine_map_of_raw_inputs():
    rows = np.array([[1, 0, 0, 0, 0, 0], [0, 2, 0, 0, 0, 0], [0, 0, 3, 0, 0, 0], [0, 0, 0, 1e-3, 0, 0],
                     [0, 0, 0, 0, -0.5, 0], [0, 0, 0, 0, 0, 2], [0.1, 0.1, 0.1, 0.1, 0.1, 0.15],
                     [90.7, 49.0, -256.9, -6.6, -1.5, -3.7]])
    u = np.random.default_rng(0).uniform(-3000, 3000, (50, 7))
    model = parse_paper_xml(HAND_WRITTEN)
    np.testing.assert_allclose(model.predict(u), u @ rows[:7] + rows[7], rtol=1e-12, atol=1e-9)


def test_written_rows_follow_the_paper_order(tmp_path):
    # Raw coefficients 1..6 on u1, u2, u1², u1·u2, u2², 1.
    model = from_raw(np.arange(1.0, 7.0)[:, None], degree=2, input_names=["a", "b"], output_names=["F"])
    path = tmp_path / "m.xml"
    write_paper_xml(model, path)
    text = path.read_text()
    rows = re.findall(r'<param name="row(\d+)">\(([^)]*)\)</param>', text)
    assert rows == [(str(k), repr(float(k))) for k in range(1, 7)]
    assert '<param name="np">2</param>' in text and '<param name="string">2nd_degree</param>' in text
    # At (a, b) = (2, 3): 1·2 + 2·3 + 3·4 + 4·6 + 5·9 + 6 = 95.
    assert read_paper_xml(path, input_names=["a", "b"]).predict(np.array([[2.0, 3.0]]))[0, 0] == 95.0


def fitted(na=0, nb=0, degree=2):
    rng = np.random.default_rng(3)
    u = rng.uniform(4000, 6000, (300, 3))
    y = np.c_[0.01 * u[:, 0] + 1e-6 * u[:, 1] * u[:, 2], 0.02 * u[:, 2]] + rng.normal(0, 0.01, (300, 2))
    return CalibrationModel(degree, na=na, nb=nb).fit(Dataset.from_arrays(u, y)), u


def test_round_trip_keeps_full_precision(tmp_path):
    model, u = fitted()
    path = tmp_path / "m.xml"
    assert write_paper_xml(model, path) < 1e-9
    loaded = read_paper_xml(path, input_names=model.input_names_, output_names=model.output_names_)
    # repr round-trips floats exactly, so the file holds the raw coefficients bit for bit.
    np.testing.assert_array_equal(loaded.coef_, to_raw(model))
    np.testing.assert_allclose(loaded.predict(u), model.predict(u), rtol=1e-10)


def test_arx_round_trip(tmp_path):
    model, u = fitted(na=1, nb=1, degree=1)
    path = tmp_path / "arx.xml"
    write_paper_xml(model, path)
    text = path.read_text()
    # ny·na + 1 + (nb+1)·nu = 2 + 1 + 2·3 = 9 rows.
    assert '<param name="na">1</param>' in text and "row9" in text and "row10" not in text
    loaded = read_paper_xml(path)
    np.testing.assert_allclose(loaded.predict(u), model.predict(u), rtol=1e-9)


def test_writing_warns_when_raw_monomials_lose_precision(tmp_path):
    # x⁵ with x = u − 1e5 on u in [1e5 − 1, 1e5 + 1]: raw terms near 1e25 cancel to size 1.
    model = model_from_fitted(
        degree=5, na=0, nb=0, normalization="center", coef=np.eye(6)[4][:, None],
        input_normalization=Normalization(np.array([1e5]), np.array([1.0])),
        output_normalization=Normalization.identity(1), input_names=["u"], output_names=["F"],
        input_range=np.array([[1e5 - 1, 1e5 + 1]]), output_range=np.array([[-1.0, 1.0]]))
    with pytest.warns(PrecisionLossWarning, match="'F'"):
        write_paper_xml(model, tmp_path / "m.xml")


def edit(pattern, replacement):
    return re.sub(pattern, replacement, HAND_WRITTEN, flags=re.DOTALL)


@pytest.mark.parametrize("text, message", [
    (edit(r'\s*<param name="row8">.*?</param>', ""),
     r"hand\.xml: 7 rowK parameters, but np=1, nu=7, ny=6, na=0, nb=0 needs 8"),
    (edit('row8', 'row9'), r"hand\.xml: row8 is missing"),
    # 1 + C(70,1) + C(71,2) + C(72,3) + C(73,4) + C(74,5) = 1 + 70 + 2485 + 59640 + 1088430 + 16108764.
    (edit('"np">1<', '"np">5<').replace('"nu">7<', '"nu">70<'), r"needs 17259390 "),
    (edit(r"\(0\t0\t3\.0", "(0\t0x\t3.0"), r"hand\.xml: row3, value 2 is '0x'; expected a finite number"),
    (edit(r"-\.5", "nan"), r"row5, value 5 is 'nan'"),
    (edit(r"\( 0 2 0 0 0 0 \)", "(0 2 0 0 0)"), r"row2 has 5 numbers; ny=6 needs 6"),
    (edit(r"\(1  0  0  0  0  0\)", "1 0 0 0 0 0"), r"row1 is '1 0 0 0 0 0'; expected numbers in parentheses"),
    (edit(r'\s*<param name="nu">7</param>', ""), r"hand\.xml: the required param 'nu' is missing"),
    (edit(r'"np">1<', '"np">one<'), r"param 'np' is 'one'; expected a whole number"),
    (edit(r'"np">1<', '"np">0<'), r"param 'np' is 0; it must be in \[1, 10\]"),
    (HAND_WRITTEN[:300], r"hand\.xml: not well-formed XML at line \d+, column \d+"),
    ("<model/>", r"root element is <model>"),
])
def test_invalid_files_are_rejected_with_a_clear_message(text, message):
    with pytest.raises(FtcalError, match=message):
        parse_paper_xml(text, "hand.xml")


def test_the_public_load_model_reads_paper_xml_like_the_cli(tmp_path):
    import ftcal

    model, u = fitted()
    path = tmp_path / "m.xml"
    write_paper_xml(model, path)
    loaded = ftcal.load_model(path)
    np.testing.assert_allclose(loaded.predict(u), model.predict(u), rtol=1e-10)
    assert set(ftcal.__all__) <= set(dir(ftcal))
