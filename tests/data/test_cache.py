"""The expected-wrench cache: hits, invalidation, damaged or planted entries, location, unwritable folders."""

import os
import warnings

import numpy as np
import pytest
from test_robot_expected import FOREARM, static_wrench
from test_robot_model import TINY_URDF

from ftcal.robot import Payload, RobotModel, expected_wrenches
from ftcal.robot.cache import cache_key, cache_path, cached, content_digest, default_cache_dir
from ftcal.runtime.errors import FtcalWarning

THETA = np.linspace(-1, 1, 7)
NAMES = ["arm_ft"]


@pytest.fixture
def tiny():
    return RobotModel.from_text(TINY_URDF, "tiny.urdf")


@pytest.fixture
def counted(tiny):
    """compute() for the tiny arm at THETA, counting its calls."""
    calls = []

    def compute():
        calls.append(1)
        return expected_wrenches(tiny, THETA[:, None])
    compute.calls = calls
    return compute


def physics():
    """The forearm's weight in the sensor frame, by hand: (n, 1 sensor, 6)."""
    return np.array([static_wrench([FOREARM], t) for t in THETA])[:, None, :]


def key_of(tiny):
    return cache_key(tiny, [THETA[:, None]], ("base",))


def test_hit_and_invalidation(tiny, counted, tmp_path):
    key = key_of(tiny)
    first = cached(key, NAMES, len(THETA), counted, tmp_path)
    assert cache_path(key, tmp_path).is_file()
    again = cached(key, NAMES, len(THETA), counted, tmp_path)
    assert len(counted.calls) == 1
    np.testing.assert_allclose(again, physics(), atol=1e-9)
    np.testing.assert_array_equal(first, again)
    loaded = tiny.with_payloads([Payload("forearm", 1.0)])
    assert cache_key(loaded, [THETA[:, None]], ("base",)) != key
    assert cache_key(tiny, [THETA[:, None] + 1e-12], ("base",)) != key
    assert cache_key(tiny, [THETA[:, None]], ("other",)) != key
    assert cache_key(RobotModel.from_text(TINY_URDF.replace("1.5", "1.6"), "t"), [THETA[:, None]], ("base",)) != key


def _save(path, key, wrenches, sensors=NAMES, digest=None, fmt="ftcal-expected-cache-entry-v2"):
    with open(path, "wb") as fh:
        np.savez(fh, format=np.array(fmt), key=np.array(key), sensors=np.array(sensors), wrenches=wrenches,
                 sha256=np.array(digest or content_digest(key, sensors, wrenches)))


def damage(kind, path, key):
    good = physics()
    if kind == "corrupt":
        path.write_bytes(b"garbage, not a zip file")
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "truncated":
        _save(path, key, good)
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    elif kind == "wrong shape":
        _save(path, key, good[:3])  # self-consistent digest, wrong number of samples
    elif kind == "non-finite":
        bad = good.copy()
        bad[2, 0, 1] = np.nan
        _save(path, key, bad)
    elif kind == "planted":  # the right key, values changed, the digest of the true values kept
        _save(path, key, good + 1.0, digest=content_digest(key, NAMES, good))
    elif kind == "missing field":
        with open(path, "wb") as fh:
            np.savez(fh, key=np.array(key), sensors=np.array(NAMES), wrenches=good)
    elif kind == "other sensors":
        _save(path, key, good, sensors=["other_ft"])


@pytest.mark.parametrize("kind", ["corrupt", "empty", "truncated", "wrong shape", "non-finite", "planted",
                                  "missing field", "other sensors"])
def test_an_entry_that_does_not_verify_is_ignored_and_recomputed(tiny, counted, tmp_path, kind):
    key = key_of(tiny)
    path = cache_path(key, tmp_path)
    path.parent.mkdir(parents=True, exist_ok=True)
    damage(kind, path, key)
    with pytest.warns(FtcalWarning, match=f"ignoring the expected-wrench cache entry {path}"):
        values = cached(key, NAMES, len(THETA), counted, tmp_path)
    assert len(counted.calls) == 1
    np.testing.assert_allclose(values, physics(), atol=1e-9)
    # ... and replaced by a good entry, used silently next time
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(cached(key, NAMES, len(THETA), counted, tmp_path), values)
    assert len(counted.calls) == 1


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_an_unwritable_cache_is_a_warning(tiny, counted, tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        with pytest.warns(FtcalWarning, match="could not write the expected-wrench cache"):
            values = cached(key_of(tiny), NAMES, len(THETA), counted, folder)
    finally:
        folder.chmod(0o755)
    np.testing.assert_allclose(values, physics(), atol=1e-9)


def test_a_cache_folder_that_is_a_file_is_a_warning(tiny, counted, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.warns(FtcalWarning, match="could not write the expected-wrench cache"):
        values = cached(key_of(tiny), NAMES, len(THETA), counted, blocker)
    np.testing.assert_allclose(values, physics(), atol=1e-9)


def test_default_location_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert default_cache_dir() == tmp_path / "ftcal"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_cache_dir() == tmp_path / "home" / ".cache" / "ftcal"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/path")  # the XDG spec says: ignore relative paths
    assert default_cache_dir() == tmp_path / "home" / ".cache" / "ftcal"
