"""Shared fixtures of the Python tests (run by ctest: python/CMakeLists.txt sets PYTHONPATH and
the tool paths). As tests/test_support.hpp does for the C++ tests: with CI set a missing Vulkan
device fails the tests instead of skipping them, and any validation-layer message fails the test
in which it arose (OCTOVK_VALIDATION=1). An old spelling's DeprecationWarning from octovk is an
error: the tests use the current names, and those that check a deprecation catch it with
pytest.warns."""

import os
import subprocess

import numpy as np
import pytest

import octovk


# Every deprecation message of the module ends its sentence with when the old name goes.
OCTOVK_DEPRECATION = ".*goes in the next release"


def pytest_configure(config):
    config.addinivalue_line("filterwarnings", f"error:{OCTOVK_DEPRECATION}:DeprecationWarning")


def running_in_ci():
    return os.environ.get("CI", "") not in ("", "0", "false")


def require(condition, why):
    """Fails under CI, skips elsewhere, when `condition` is false."""
    if not condition:
        if running_in_ci():
            pytest.fail(why + " (CI is set: not skipped)")
        pytest.skip(why)


@pytest.fixture(scope="session")
def context():
    try:
        ctx = octovk.default_context()
    except octovk.Error as e:
        require(False, f"no Vulkan device: {e}")
    expected = os.environ.get("OCTOVK_EXPECT_DRIVER", "")
    if expected and expected not in ctx.device.driver:
        pytest.fail(f"OCTOVK_EXPECT_DRIVER='{expected}' but the device's driver is "
                    f"'{ctx.device.driver}'")
    return ctx


@pytest.fixture(autouse=True)
def no_validation_messages():
    before = octovk.validation_message_count()
    yield
    assert octovk.validation_message_count() == before, \
        "the Vulkan validation layer reported messages (on stderr) during this test"


def tool(name):
    """A path ctest passes in the environment (OCTOVK_PY_ORACLE, OCTOVK_GRAPH2TREE, ...)."""
    path = os.environ.get(name, "")
    if not path or not os.access(path, os.X_OK):
        pytest.fail(f"{name} is not set to an executable ('{path}'): run these tests through "
                    "ctest (cd build && ctest -R python), or install octomap-tools")
    return path


def octomap_data(name):
    return os.path.join(os.environ.get("OCTOVK_OCTOMAP_DATA_DIR",
                                       "/usr/share/doc/liboctomap-dev/examples/data"), name)


def run(args, cwd=None, env=None):
    done = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True)
    assert done.returncode == 0, f"{args}: {done.stdout}{done.stderr}"
    return done.stdout


def room_scans(seed=7, scans=4, points=800, z_spread=0.3):
    """Random scans of a room-sized region, as tests/query_test.cpp's buildMap makes them."""
    rng = np.random.default_rng(seed)
    out = []
    for scan in range(scans):
        origin = np.array([0.3 * scan, 0.1, 0.0], np.float32)
        d = rng.uniform(-1, 1, (points, 3)).astype(np.float32)
        d[:, 2] *= z_spread
        d = d[np.linalg.norm(d, axis=1) > 1e-3]
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        r = (1.5 + 0.5 * rng.uniform(-1, 1, (len(d), 1))).astype(np.float32)
        out.append((np.ascontiguousarray(origin + d * r, np.float32), origin))
    return out


def unproject(depth, fx, fy, cx, cy, depth_scale, with_mask=False):
    """DepthImage's unprojection in float32, in its order of operations (include/octovk/scan.hpp);
    with_mask: also the (H, W) mask of the pixels kept (the others are skipped)."""
    h, w = depth.shape
    d = depth.astype(np.float32)
    v, u = np.meshgrid(np.arange(h, dtype=np.float32), np.arange(w, dtype=np.float32),
                       indexing="ij")
    with np.errstate(divide="ignore", invalid="ignore"):
        z = d / np.float32(depth_scale)
        keep = np.isfinite(d) & (d != 0) & np.isfinite(z) & (z != 0)
        x = ((u - np.float32(cx)) * z) / np.float32(fx)
        y = ((v - np.float32(cy)) * z) / np.float32(fy)
    points = np.ascontiguousarray(np.stack([x[keep], y[keep], z[keep]], axis=1), np.float32)
    return (points, keep) if with_mask else points
