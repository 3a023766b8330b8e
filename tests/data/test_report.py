"""The HTML report: self-contained page, one image per applicable figure, tables equal to
metrics computed here with numpy, skipped figures explained, and a real browser render."""

import base64
import io
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser

import matplotlib
import matplotlib.image as mpimg
import numpy as np
import pytest

from ftcal.core.dataset import Dataset
from ftcal.core.model import CalibrationModel
from ftcal.core.select import Candidate, cross_validate
from ftcal.core.solvers.lasso import Lasso
from ftcal.report import ModelRun, build_report, evaluate_run as evaluate
from ftcal.report.figures import MAX_LINE_POINTS, envelope_indices
from ftcal.report.runs import natural_key
from ftcal.runtime.errors import FtcalError
from ftcal.sim.synthetic import synthetic_recordings

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FORCES, TORQUES = [0, 1, 2], [3, 4, 5]
MAX_PAGE_BYTES = 5_000_000


# ------------------------------------------------------------------ helpers
class _Tables(HTMLParser):
    """Every <table> as (caption, list of rows of cell texts)."""

    def __init__(self):
        super().__init__()
        self.tables, self._cell, self._row, self._caption = [], None, None, None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append(["", []])
        elif tag == "caption":
            self._caption = ""
        elif tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = ""

    def handle_endtag(self, tag):
        if tag == "caption":
            self.tables[-1][0], self._caption = self._caption, None
        elif tag in ("td", "th"):
            self._row.append(self._cell.strip())
            self._cell = None
        elif tag == "tr":
            self.tables[-1][1].append(self._row)

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data
        elif self._caption is not None:
            self._caption += data


def parse_tables(page: str) -> dict[str, list[list[str]]]:
    parser = _Tables()
    parser.feed(page)
    return {caption: rows for caption, rows in parser.tables}


def table(page: str, caption_start: str) -> dict[str, dict[str, str]]:
    """The table whose caption starts with ``caption_start``, as {row name: {column header: cell}}."""
    matches = [rows for caption, rows in parse_tables(page).items() if caption.startswith(caption_start)]
    assert len(matches) == 1, f"expected one table captioned {caption_start!r}"
    header, *rows = matches[0]
    return {row[0]: dict(zip(header, row)) for row in rows}


def f4(value: float) -> str:
    return f"{value:.4f}"


def norm_rmse(y, y_hat, cols):
    """The paper's RMSE of force (torque) norm, by hand."""
    diff = np.sqrt((y[:, cols] ** 2).sum(axis=1)) - np.sqrt((y_hat[:, cols] ** 2).sum(axis=1))
    return float(np.sqrt(np.mean(diff ** 2)))


def figure_images(page: str) -> dict[str, bytes]:
    """PNG bytes of each <figure id="fig-..."> image."""
    found = re.findall(r'<figure id="fig-([\w-]+)"><img src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    return {key: base64.b64decode(data) for key, data in found}


def assert_not_blank(rgb: np.ndarray, min_colors: int) -> None:
    """Real content: the pixel values vary and there are several distinct colours."""
    rgb = rgb[..., :3]
    assert float(rgb.std()) > 0.05
    levels = (rgb.reshape(-1, 3) * 15).round().astype(np.int64)  # 16 levels per channel
    colors = np.unique(levels @ np.array([256, 16, 1]))
    assert len(colors) >= min_colors


# ------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def data():
    """7 load cases, two recordings each; the second recording of l1kg and l5kg is held out."""
    full = synthetic_recordings(14, 300, seed=7)
    held_out = np.isin(full.segments, [8, 10])
    return full.subset(~held_out), full.subset(held_out)


@pytest.fixture(scope="module")
def models(data):
    train, _ = data
    return {"np1": CalibrationModel(1).fit(train),
            "np2": CalibrationModel(2).fit(train),
            "np2 λ=1": CalibrationModel(2, solver=Lasso(1.0)).fit(train),
            "np2 λ=10": CalibrationModel(2, solver=Lasso(10.0)).fit(train)}


@pytest.fixture(scope="module")
def cv(data):
    train, _ = data
    candidates = [Candidate(1, "none", None), Candidate(2, "none", None),
                  Candidate(2, "lasso", 1.0), Candidate(2, "lasso", 10.0)]
    return cross_validate(train, candidates, n_folds=3)


@pytest.fixture(scope="module")
def report(tmp_path_factory, data, models, cv):
    train, validation = data
    runs = [evaluate(model, validation, name=name, train=train) for name, model in models.items()]
    out = tmp_path_factory.mktemp("report") / "report.html"
    returned = build_report(runs, validation, out, train=train, cv=cv, title="test report",
                            notes=["a note <with> markup"])
    assert returned == out
    return out, out.read_text(encoding="utf-8")


# ------------------------------------------------------------------ page
def test_page_is_self_contained(report):
    _, page = report
    assert page.startswith("<!DOCTYPE html>")
    assert not re.search(r"<(script|link|iframe|object|embed)\b", page, re.IGNORECASE)
    assert "url(" not in page and "@import" not in page
    sources = re.findall(r'\bsrc="([^"]*)"', page)
    assert sources and all(s.startswith("data:image/png;base64,") for s in sources)
    assert all(h.startswith("#") for h in re.findall(r'\bhref="([^"]*)"', page))
    assert not re.search(r"https?://", page)


def test_page_is_small(report):
    path, _ = report
    assert path.stat().st_size < MAX_PAGE_BYTES


def test_one_png_per_applicable_figure(report):
    _, page = report
    images = figure_images(page)
    assert set(images) == {"errors-least-squares", "errors-lasso", "norms-least-squares", "norms-lasso",
                           "readings", "wrench-space", "temperature", "validation-curve", "lasso-path",
                           "cross-validation"}
    assert page.count("<img ") == len(images)
    for key, png in images.items():
        assert png.startswith(b"\x89PNG\r\n\x1a\n"), key
        assert_not_blank(mpimg.imread(io.BytesIO(png), format="png"), min_colors=8)
    assert 'class="skipped"' not in page


def test_runs_table_matches_metrics_computed_here(report, data, models):
    _, page = report
    train, validation = data
    rows = table(page, "Models on the validation data")
    assert list(rows) == list(models)
    for name, model in models.items():
        row = rows[name]
        y_val_hat = model.predict(validation.inputs, warn_out_of_range=False)
        y_train_hat = model.predict(train.inputs, warn_out_of_range=False)
        assert row["validation force-norm RMSE [N]"] == f4(norm_rmse(validation.outputs, y_val_hat, FORCES))
        assert row["validation torque-norm RMSE [N·m]"] == f4(norm_rmse(validation.outputs, y_val_hat, TORQUES))
        assert row["train force-norm RMSE [N]"] == f4(norm_rmse(train.outputs, y_train_hat, FORCES))
        assert row["train torque-norm RMSE [N·m]"] == f4(norm_rmse(train.outputs, y_train_hat, TORQUES))
        error_norm = np.sqrt(np.mean(((validation.outputs - y_val_hat)[:, FORCES] ** 2).sum(axis=1)))
        assert row["validation RMSE of the force error norm [N]"] == f4(error_norm)
        # And the same numbers as the library's own score(), formatted alike.
        score = model.metrics(validation, warn_out_of_range=False)
        assert row["validation force-norm RMSE [N]"] == f4(score["force_norm_rmse"])
        assert row["nonzero"] == str(np.count_nonzero(model.coef_))
    # Coefficient counts per the paper: ny · (1 + Σ_p C(nu+p−1, p)), nu = 7, ny = 6.
    assert rows["np1"]["coefficients"] == "48"
    # The paper's count for the affine model: raw coefficients above 1e-9 of numpy's lstsq on [u, 1].
    raw = np.linalg.lstsq(np.column_stack([train.inputs, np.ones(train.n_samples)]), train.outputs, rcond=None)[0]
    assert rows["np1"]["raw > 1e-9"] == str(int((np.abs(raw) > 1e-9).sum()))
    assert rows["np2"]["coefficients"] == "216"
    assert rows["np1"]["λ"] == "–" and rows["np2 λ=10"]["λ"] == "10"
    assert rows["np2 λ=10"]["solver"] == "lasso" and rows["np2"]["solver"] == "lstsq"


def test_per_axis_tables_match_numpy(report, data, models):
    _, page = report
    _, validation = data
    rmse_rows = table(page, "Validation RMSE per axis")
    fit_rows = table(page, "Validation BestFit")
    max_rows = table(page, "Validation largest absolute error")
    y = validation.outputs
    for name, model in models.items():
        err = y - model.predict(validation.inputs, warn_out_of_range=False)
        rmse = np.sqrt(np.mean(err ** 2, axis=0))
        best_fit = 1.0 - np.sqrt(np.mean(err ** 2, axis=0) / np.mean((y - y.mean(axis=0)) ** 2, axis=0))
        worst = np.abs(err).max(axis=0)
        for j, axis in enumerate(("Fx [N]", "Fy [N]", "Fz [N]", "Tx [N·m]", "Ty [N·m]", "Tz [N·m]")):
            assert rmse_rows[name][axis] == f4(rmse[j])
            assert max_rows[name][axis] == f4(worst[j])
            assert fit_rows[name][axis.split()[0] + " [%]"] == f"{100 * best_fit[j]:.2f}"


def test_ranges_groups_and_cv_tables(report, data, cv):
    _, page = report
    train, validation = data
    ranges = table(page, "Range of the expected wrench")
    assert ranges["Fz [N]"]["validation min"] == f"{validation.outputs[:, 2].min():.2f}"
    assert ranges["T [°C]"]["training max"] == f"{train.inputs[:, 6].max():.2f}"
    groups = table(page, "Samples per group")
    assert list(groups) == ["l0kg", "l1kg", "l2kg", "l5kg", "l7kg", "l9kg", "l10kg"]
    assert groups["l5kg"]["validation samples"] == "300" and groups["l0kg"]["validation samples"] == "0"
    assert groups["l5kg"]["training samples"] == "300" and groups["l1kg"]["validation samples"] == "300" and groups["l0kg"]["training samples"] == "600"
    rows = table(page, "Grouped 3-fold cross-validation")
    for s in cv.scores:
        assert rows[s.candidate.label][f"validation {cv.metric}"] == f4(np.mean(s.fold_scores))


def test_notes_are_escaped(report):
    _, page = report
    assert "<li>a note &lt;with&gt; markup</li>" in page


def test_skipped_figures_say_why(tmp_path):
    """No temperature input, no training set, one least-squares model: three figures skipped."""
    full = synthetic_recordings(2, 300, seed=3)
    data = Dataset(full.inputs[:, :6], full.outputs, full.input_names[:6], full.output_names,
                   full.segments, full.groups)
    model = CalibrationModel(1).fit(data)
    out = build_report([evaluate(model, data)], data, tmp_path / "r.html")
    page = out.read_text(encoding="utf-8")
    assert set(figure_images(page)) == {"errors-least-squares", "norms-least-squares", "readings", "wrench-space"}
    skipped = re.findall(r'<p class="skipped">([^<]*)</p>', page)
    assert len(skipped) == 3
    assert any("temperature" in s for s in skipped)
    assert any("validation curve" in s for s in skipped)
    assert any("LASSO" in s for s in skipped)
    # The contents list only what the page shows; the skipped sections are gathered at the end.
    contents = re.findall(r'<li><a href="#([^"]+)">', page.split("</nav>")[0])
    assert contents == ["models", "errors", "norms", "axes", "data", "not-shown"]
    assert all(f'<section id="{anchor}">' in page for anchor in contents)
    assert '<section id="temperature">' not in page and "<h3>Temperature effect</h3>" in page
    assert "training" not in table(page, "Range of the expected wrench")["Fx [N]"]


def test_bad_runs_are_refused_and_nothing_is_written(tmp_path, data, models):
    _, validation = data
    run = evaluate(models["np1"], validation)
    target = tmp_path / "r.html"
    with pytest.raises(FtcalError, match="at least one"):
        build_report([], validation, target)
    with pytest.raises(FtcalError, match="unique"):
        build_report([run, run], validation, target)
    short = ModelRun("short", run.model, None, run.validation_metrics, run.validation_prediction[:-1])
    with pytest.raises(FtcalError, match="shape"):
        build_report([short], validation, target)
    no_outputs = Dataset(validation.inputs, None, validation.input_names, (), validation.segments,
                         validation.groups)
    with pytest.raises(FtcalError, match="reference outputs"):
        build_report([run], no_outputs, target)
    assert list(tmp_path.iterdir()) == []


def test_report_leaves_matplotlib_settings_alone(tmp_path, data, models):
    _, validation = data
    before, backend = dict(matplotlib.rcParams), matplotlib.get_backend()
    build_report([evaluate(models["np1"], validation)], validation, tmp_path / "r.html")
    assert dict(matplotlib.rcParams) == before
    assert matplotlib.get_backend() == backend


def test_import_does_not_load_pyplot():
    code = "import sys, ftcal.report; assert 'matplotlib.pyplot' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


# ------------------------------------------------------------------ helpers of the figures
def test_envelope_keeps_extremes_within_budget():
    rng = np.random.default_rng(0)
    values = rng.standard_normal(123_457)
    idx = envelope_indices(values)
    assert len(idx) <= MAX_LINE_POINTS
    assert np.all(np.diff(idx) > 0)
    assert values.argmax() in idx and values.argmin() in idx
    np.testing.assert_array_equal(envelope_indices(values[:100]), np.arange(100))


def test_load_cases_sort_by_number():
    assert sorted(["l10kg", "l2kg", "l0kg", "l9kg"], key=natural_key) == ["l0kg", "l2kg", "l9kg", "l10kg"]


# ------------------------------------------------------------------ browser
@pytest.mark.browser
@pytest.mark.skipif(CHROMIUM is None, reason="Chromium is not installed (apt-get install chromium)")
def test_page_renders_in_headless_chromium(report, tmp_path):
    path, _ = report
    shot = tmp_path / "page.png"
    command = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
               "--disable-background-networking", "--disable-component-update", "--disable-sync",
               f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1280,4000",
               f"--screenshot={shot}", path.resolve().as_uri()]
    result = subprocess.run(command, capture_output=True, text=True, timeout=180)
    assert shot.exists(), f"no screenshot; chromium said: {result.stderr[-2000:]}"
    image = mpimg.imread(shot)
    assert image.shape[:2] == (4000, 1280)
    assert_not_blank(image, min_colors=30)
    # Figures rendered, not just text: a good part of the page below the title is non-white.
    body = image[400:, :, :3]
    assert float(np.mean(body.min(axis=2) < 0.9)) > 0.05
