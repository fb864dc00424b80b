"""The module's surface: the stub octovk.pyi names exactly what the module binds, with the same
parameters; every docstring says something and names its parameters; library errors arrive as
octovk.Error subclasses with code, message and scan; a map keeps its Context alive."""

import ast
import gc
import os
import pydoc
import re
import weakref

import numpy as np
import pytest

import octovk

STUB = os.path.join(os.path.dirname(octovk.__file__), "octovk.pyi")
TYPE_ALIASES = {"ArrayLike", "Vector3", "PoseLike", "PathLike", "FloatArray", "ByteArray",
                "ColorFold"}


def stub_tree():
    with open(STUB) as f:
        return ast.parse(f.read())


def public(names):
    return {n for n in names if not n.startswith("__") and n != "_default_context"}


def split_top_level(text):
    """Splits a signature's parameters at commas outside brackets and quotes."""
    parts, depth, current, quote = [], 0, "", None
    for c in text:
        if quote:
            quote = None if c == quote else quote
        elif c in "'\"":
            quote = c
        elif c in "([{<":
            depth += 1
        elif c in ")]}>":
            depth -= 1
        elif c == "," and depth == 0:
            parts.append(current.strip())
            current = ""
            continue
        current += c
    if current.strip():
        parts.append(current.strip())
    return parts


def bound_parameters(function):
    """(name, has default) of each parameter in pybind11's signature line; '*' for keyword-only."""
    first = function.__doc__.splitlines()[0]
    inner = first[first.index("(") + 1:first.rindex(") ->")]
    out = []
    for p in split_top_level(inner):
        name = p.split(":")[0].split("=")[0].strip()
        if name != "self":
            out.append((name, "=" in p))
    return out


def stub_parameters(node):
    a = node.args
    positional = a.posonlyargs + a.args
    defaults = [False] * (len(positional) - len(a.defaults)) + [True] * len(a.defaults)
    out = [(p.arg, d) for p, d in zip(positional, defaults) if p.arg != "self"]
    if a.kwonlyargs:
        out.append(("*", False))
        out += [(p.arg, d is not None) for p, d in zip(a.kwonlyargs, a.kw_defaults)]
    return out


def test_stub_names_what_the_module_binds():
    tree = stub_tree()
    stub_names = set()
    for node in tree.body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
            stub_names.add(node.name)
        elif isinstance(node, ast.Assign):
            stub_names |= {t.id for t in node.targets} - TYPE_ALIASES
    assert public(dir(octovk)) == stub_names


def stub_members(node, classes):
    """The names a stub class declares, with those of its stub base classes (ColorMap(Map))."""
    members = set()
    for base in node.bases:
        if isinstance(base, ast.Name) and base.id in classes:
            members |= stub_members(classes[base.id], classes)
    for item in node.body:
        if isinstance(item, ast.FunctionDef):
            members.add(item.name)
        elif isinstance(item, ast.AnnAssign):
            members.add(item.target.id)
        elif isinstance(item, ast.Assign):
            members |= {t.id for t in item.targets}
    return members


def test_stub_classes_and_signatures_match_the_module():
    checked = 0
    classes = {n.name: n for n in stub_tree().body if isinstance(n, ast.ClassDef)}
    for node in stub_tree().body:
        if isinstance(node, ast.FunctionDef):
            assert stub_parameters(node) == bound_parameters(getattr(octovk, node.name)), node.name
            checked += 1
        if not isinstance(node, ast.ClassDef) or issubclass(getattr(octovk, node.name), Exception):
            continue
        cls = getattr(octovk, node.name)
        for item in node.body:
            if isinstance(item, ast.FunctionDef):
                if not any(isinstance(d, ast.Name) and d.id == "property"
                           for d in item.decorator_list):
                    bound = getattr(cls, item.name)
                    assert stub_parameters(item) == bound_parameters(bound), \
                        f"{node.name}.{item.name}"
                    checked += 1
        members = stub_members(node, classes)
        if hasattr(cls, "__members__"):  # an enum: its values
            assert set(cls.__members__) == members - {"name", "value", "__int__"}, node.name
        else:
            bound = public(dir(cls)) - {"_pybind11_conduit_v1_"}
            assert bound == members - {"__init__"}, node.name
    assert checked > 25


def test_docstrings_say_something_and_name_their_parameters():
    described = 0
    for name in public(dir(octovk)):
        obj = getattr(octovk, name)
        assert obj.__doc__ and len(obj.__doc__.strip()) > 20, name
        functions = []
        if isinstance(obj, type) and not issubclass(obj, Exception) and \
                not hasattr(obj, "__members__"):  # pybind11 writes the enums' methods
            functions = [(f"{name}.{n}", getattr(obj, n)) for n in public(dir(obj)) | {"__init__"}
                         if callable(getattr(obj, n)) and getattr(obj, n).__doc__ and
                         getattr(obj, n).__doc__.startswith(n + "(self")]
        elif callable(obj) and not isinstance(obj, type):
            functions = [(name, obj)]
        for label, f in functions:
            described += 1
            lines = f.__doc__.splitlines()
            text = "\n".join(lines[1:])
            assert len(text.strip()) > 15, f"{label} has no description"
            for p, _ in bound_parameters(f):
                if p not in ("*", "out", "self"):
                    assert re.search(r"\b" + p + r"\b", text), f"{label}'s doc does not name {p}"
    assert described > 25


def test_help_of_map_tells_what_it_does():
    text = pydoc.render_doc(octovk.Map, renderer=pydoc.plaintext)
    for words in ("insert_point_cloud(self", "OctoMap's insertPointCloud", "cast_rays(self",
                  "castRay", "search(self", "leaves_in_box(self", "leaf_bbx_iterator",
                  "write(self", ".bt", "read(path", "submit_point_cloud(self", "flush(self",
                  "Ctrl-C", "GIL", "max_device_bytes", "trim(self"):
        assert words in text, words


# ---- errors ----

def test_every_error_code_has_its_subclass():
    classes = {octovk.NoDeviceError, octovk.MissingFeatureError, octovk.InvalidArgumentError,
               octovk.OutOfDeviceMemoryError, octovk.VulkanError, octovk.IoError,
               octovk.FormatError, octovk.OutOfHostMemoryError, octovk.InternalError}
    assert len(classes) == len(octovk.ErrorCode.__members__) == 9
    for cls in classes:
        assert issubclass(cls, octovk.Error) and cls.__module__ == "octovk"
    assert issubclass(octovk.InvalidArgumentError, ValueError)
    assert issubclass(octovk.OutOfDeviceMemoryError, MemoryError)
    assert issubclass(octovk.IoError, OSError)


def test_library_errors_carry_code_and_message(context, tmp_path):
    with pytest.raises(octovk.InvalidArgumentError) as e:
        octovk.Map(resolution=-1)
    assert e.value.code == octovk.ErrorCode.INVALID_ARGUMENT
    assert "resolution" in e.value.message and str(e.value) == e.value.message
    assert e.value.scan == 0
    with pytest.raises(octovk.IoError) as e:
        octovk.Map.read(tmp_path / "missing.bt")
    assert e.value.code == octovk.ErrorCode.IO and "missing.bt" in e.value.message
    (tmp_path / "bad.bt").write_bytes(b"# Octomap OcTree binary file\nnot a tree\n")
    with pytest.raises(octovk.FormatError) as e:
        octovk.Map.read(str(tmp_path / "bad.bt"))
    assert e.value.code == octovk.ErrorCode.FORMAT and "bad.bt" in e.value.message
    with pytest.raises(octovk.Error):
        octovk.Map(0.1).write(tmp_path / "map.xyz")


def test_a_late_error_names_its_scan_and_the_map_keeps_the_scans_before(context):
    m = octovk.Map(0.05, max_device_bytes=3 << 20)
    first = m.submit_point_cloud(np.float32([[0.5, 0, 0], [0, 0.5, 0]]), (0, 0, 0))
    d = np.random.default_rng(0).normal(size=(4000, 3)).astype(np.float32)
    d = np.ascontiguousarray(d / np.linalg.norm(d, axis=1, keepdims=True) * np.float32(8))
    second = m.submit_point_cloud(d, (0, 0, 0))
    with pytest.raises(octovk.OutOfDeviceMemoryError) as e:
        m.flush()
    assert e.value.scan == second
    assert "max_device_bytes" in e.value.message
    assert [s.ticket for s in m.take_scan_stats()] == [first]
    assert m.device_bytes() <= 3 << 20
    # The map keeps working.
    m.insert_point_cloud(np.float32([[0.2, 0.2, 0]]), (0, 0, 0))
    assert m.search(np.float32([[0.2, 0.2, 0]]))[0][0] == int(octovk.CellState.OCCUPIED)


def test_version_is_the_cmake_projects():
    with open(os.path.join(os.path.dirname(__file__), "..", "..", "CMakeLists.txt")) as f:
        version = re.search(r"project\(octovk VERSION ([0-9.]+)", f.read()).group(1)
    assert octovk.__version__ == version


def test_cell_states_compare_with_search_results(context):
    # An IntEnum: numpy and torch compare their uint8 states with it as with a number.
    import torch
    m = octovk.Map(0.1)
    m.insert_point_cloud(np.float32([[1.0, 0, 0]]), (0, 0, 0))
    state, _, _ = m.search(np.float32([[1.0, 0, 0], [0.5, 0, 0], [-3, 0, 0]]))
    np.testing.assert_array_equal(state, [2, 1, 0])
    S = octovk.CellState
    np.testing.assert_array_equal(state == S.OCCUPIED, [True, False, False])
    np.testing.assert_array_equal(state == S.FREE, [False, True, False])
    np.testing.assert_array_equal(state != S.UNKNOWN, [True, True, False])
    assert (torch.from_dlpack(state) == S.FREE).tolist() == [False, True, False]
    assert [S(s) for s in state] == [S.OCCUPIED, S.FREE, S.UNKNOWN]
    assert S.FREE == 1 and S(2).name == "OCCUPIED" and isinstance(S.FREE, int)


# ---- lifetime, parameters, memory ----

def test_a_map_keeps_its_context_alive(context):
    ctx = octovk.Context()
    alive = weakref.ref(ctx)
    m = octovk.Map(0.1, context=ctx)
    del ctx
    gc.collect()
    assert alive() is not None and m.context is alive()
    m.insert_point_cloud(np.float32([[1, 0, 0]]), (0, 0, 0))
    assert m.node_count() > 16
    del m
    gc.collect()
    assert alive() is None


def test_maps_use_the_default_context_and_report_their_parameters(context):
    m = octovk.Map(0.2, prob_hit=0.8, prob_miss=0.3, clamping_min=0.2, clamping_max=0.9,
                   occupancy_threshold=0.6, max_device_bytes=64 << 20)
    assert m.context is octovk.default_context() is context
    assert (m.resolution, m.prob_hit, m.prob_miss, m.clamping_min, m.clamping_max,
            m.occupancy_threshold, m.max_device_bytes) == (0.2, 0.8, 0.3, 0.2, 0.9, 0.6, 64 << 20)
    assert any(d.name == context.device.name for d in octovk.devices())


def test_counts_memory_and_trim(context):
    m = octovk.Map(0.1)
    empty = m.device_bytes_by_use()
    points = np.random.default_rng(1).uniform(-2, 2, (20000, 3)).astype(np.float32)
    m.insert_point_cloud(points, (0, 0, 0))
    grown = m.device_bytes_by_use()
    assert grown.scratch > empty.scratch
    assert grown.total == (grown.pool + grown.leaf_boxes + grown.scratch + grown.queries
                           + grown.changes + grown.distance_fields) == m.device_bytes()
    leaves = m.leaf_count()
    assert m.node_count() > leaves > 1000
    assert len(m.leaves()[0]) == leaves
    m.trim()
    assert m.device_bytes_by_use().scratch < grown.scratch
    assert m.leaf_count() == leaves


def test_change_detection_follows_the_cpp_api(context):
    """The change set through Python: OctoMap's semantics are checked key for key by the C++
    oracle tests (tests/change_detection_test.cpp); here the binding's shapes, flags and counts."""
    m = octovk.Map(0.1)
    assert not m.is_change_detection_enabled()
    rng = np.random.default_rng(7)
    d = rng.normal(size=(800, 3)).astype(np.float32)
    pts = (d / np.linalg.norm(d, axis=1, keepdims=True) * 2.0).astype(np.float32)
    m.insert_point_cloud(pts, (0, 0, 0))
    assert m.num_changes_detected() == 0
    keys, created = m.changed_keys()
    assert keys.shape == (0, 3) and created.shape == (0,)
    m.enable_change_detection(True)
    assert m.is_change_detection_enabled()
    assert m.device_bytes_by_use().changes > 4096 * 16
    m.insert_point_cloud(pts * 1.5, (0.05, 0, 0))
    keys, created = m.changed_keys()
    assert keys.dtype == np.uint16 and keys.shape[1] == 3 and created.dtype == np.uint8
    assert len(keys) == m.num_changes_detected() > 100
    assert len({tuple(k) for k in keys}) == len(keys)  # a set: each key once
    assert set(np.unique(created)) <= {0, 1} and created.sum() > 0
    m.reset_change_detection()
    assert m.num_changes_detected() == 0


def test_clear_box_sets_the_leaves_in_it_to_the_lower_clamping_bound(context):
    """clear_box through Python; OctoMap's clear_bbx is checked node for node by the C++ oracle
    tests (tests/map_edit_test.cpp)."""
    m = octovk.Map(0.1)
    rng = np.random.default_rng(3)
    d = rng.normal(size=(2000, 3)).astype(np.float32)
    m.insert_point_cloud((d / np.linalg.norm(d, axis=1, keepdims=True) * 2.0).astype(np.float32),
                         (0, 0, 0))
    centers, sizes, log_odds = m.leaves_in_box((-2.5, -2.5, -0.3), (2.5, 2.5, 0.3))
    assert len(log_odds) > 50 and (log_odds > -1.9).any()
    m.clear_box((-2.5, -2.5, -0.3), (2.5, 2.5, 0.3))
    centers, sizes, log_odds = m.leaves_in_box((-2.5, -2.5, -0.3), (2.5, 2.5, 0.3))
    clamp_min = np.float32(np.log(0.1192 / (1 - 0.1192)))
    assert np.allclose(log_odds, clamp_min)
    with pytest.raises(octovk.InvalidArgumentError):
        m.clear_box((1, 0, 0), (0, 1, 1))


def test_keep_box_keeps_the_leaves_in_it_and_frees_the_rest(context):
    """keep_box through Python; the tree is checked node for node against OctoMap by the C++
    oracle tests (tests/keep_box_test.cpp)."""
    m = octovk.Map(0.1)
    rng = np.random.default_rng(4)
    d = rng.normal(size=(2000, 3)).astype(np.float32)
    m.insert_point_cloud((d / np.linalg.norm(d, axis=1, keepdims=True) * 2.0).astype(np.float32),
                         (0, 0, 0))
    lo, hi = (-1.0, -0.5, -0.3), (1.0, 0.5, 0.3)
    before = m.leaves_in_box(lo, hi)
    nodes = m.node_count()
    m.keep_box(lo, hi)
    assert m.node_count() < nodes
    centers, sizes, log_odds = m.leaves()
    kept = m.leaves_in_box(lo, hi)
    # every leaf left is one the box's iterator visited, with its value
    assert len(log_odds) == len(kept[2]) == len(before[2]) > 50
    order = lambda c: np.lexsort(c.T)
    assert np.array_equal(centers[order(centers)], before[0][order(before[0])])
    assert np.array_equal(log_odds[order(centers)], before[2][order(before[0])])
    with pytest.raises(octovk.InvalidArgumentError):
        m.keep_box((0, 0, float("nan")), (1, 1, 1))
    assert m.node_count() > 0
    pool = m.device_bytes_by_use().pool
    m.compact()  # the freed blocks go back to the device; the tree stays
    assert m.device_bytes_by_use().pool < pool
    assert m.node_count() > 0
    centers_after, _, log_odds_after = m.leaves()
    assert np.array_equal(centers_after[order(centers_after)], centers[order(centers)])
    assert np.array_equal(log_odds_after[order(centers_after)], log_odds[order(centers)])
    m.keep_box((-1, -1, -1), (1e6, 1, 1))  # a corner outside the map: nothing is kept
    assert m.node_count() == 0 and len(m.leaves()[2]) == 0


# ---- one name for one thing, units in names; the old spellings warn for one release ----

def test_old_spellings_warn_and_still_work(context, tmp_path):
    points = np.float32([[1.0, 0, 0], [0, 1.5, 0]])
    renamed = octovk.Map(0.1)
    renamed.insert_point_cloud(points, (0, 0, 0), max_range_m=1.2)
    renamed.write(tmp_path / "new.ot")
    old = octovk.Map(0.1)
    with pytest.warns(DeprecationWarning, match="max_range is deprecated: name it max_range_m"):
        old.insert_point_cloud(points, (0, 0, 0), max_range=1.2)
    old.write(tmp_path / "old.ot")
    assert (tmp_path / "old.ot").read_bytes() == (tmp_path / "new.ot").read_bytes()
    with pytest.warns(DeprecationWarning, match="max_range_m"):
        hit, _ = old.cast_rays((0, 0, 0), points, max_range=0.5)
    np.testing.assert_array_equal(hit, old.cast_rays((0, 0, 0), points, max_range_m=0.5)[0])
    with pytest.warns(DeprecationWarning, match="max_range_m"):
        old.submit_depth_image(np.full((2, 2), 5000, np.uint16), 1, 1, 0.5, 0.5, 5000,
                               max_range=2.0)
    old.flush()
    # device_bytes() is the total, an int, as C++'s deviceBytes(); its breakdown has its own name.
    total, by_use = old.device_bytes(), old.device_bytes_by_use()
    assert isinstance(total, int) and total == by_use.total > 0
    with pytest.warns(DeprecationWarning, match=r"device_bytes_by_use\(\)\.pool"):
        assert total.pool == by_use.pool
    with pytest.raises(AttributeError):
        total.nothing_of_that_name
    # Context(device=...) is C++'s selector (Context.device is the DeviceInfo).
    with pytest.warns(DeprecationWarning, match="name it selector"):
        by_old_name = octovk.Context(device=context.device.index, ray_query=False)
    assert by_old_name.device.name == context.device.name
    assert not by_old_name.device.ray_query_enabled
    assert octovk.Context(selector=context.device.index,
                          enable_ray_query=False).device.name == context.device.name
    with pytest.warns(DeprecationWarning, match="max_time_difference_s"):
        with pytest.raises(octovk.IoError):
            octovk.read_tum_sequence(tmp_path / "missing", max_time_difference=0.1)


def test_properties_never_wait_methods_that_read_the_map_do(context):
    """The rule between a property and a method: a property never waits for the device nor
    raises a scan's error (scans_in_flight); reading the map is a method (node_count())."""
    m = octovk.Map(0.05, max_device_bytes=3 << 20)
    d = np.random.default_rng(0).normal(size=(4000, 3)).astype(np.float32)
    d = np.ascontiguousarray(d / np.linalg.norm(d, axis=1, keepdims=True) * np.float32(8))
    m.submit_point_cloud(d, (0, 0, 0))  # refused by the device under the cap
    assert m.scans_in_flight in (0, 1) and m.resolution == 0.05  # no wait, no error
    with pytest.raises(octovk.OutOfDeviceMemoryError):
        m.node_count()
    assert isinstance(type(m).scans_in_flight, property)
    assert not isinstance(type(m).__dict__.get("node_count"), property)


# ---- key helpers ----

def test_key_helpers_turn_changed_keys_into_coordinates(context):
    import torch
    m = octovk.Map(0.1)
    m.enable_change_detection(True)
    m.insert_point_cloud(np.float32([[1.0, 0.5, 0.25], [-2.0, 0.0, 0.75]]), (0, 0, 0))
    keys, created = m.changed_keys()
    centres = octovk.key_to_coord(m.resolution, keys)
    assert centres.dtype == np.float32 and centres.shape == keys.shape
    np.testing.assert_array_equal(
        centres, ((keys.astype(np.float64) - 32768 + 0.5) * 0.1).astype(np.float32))
    # Each centre lies in its own cell, and the map knows every changed cell.
    np.testing.assert_array_equal(octovk.coord_to_key(m.resolution, centres), keys)
    assert (m.search(centres)[0] != octovk.CellState.UNKNOWN).all()
    # The end points' cells are occupied and among the changes.
    ends = octovk.coord_to_key(0.1, np.float32([[1.0, 0.5, 0.25], [-2.0, 0.0, 0.75]]))
    np.testing.assert_array_equal(ends, [[32778, 32773, 32770], [32748, 32768, 32775]])
    assert {tuple(k) for k in ends} <= {tuple(k) for k in keys}
    # A single key, float64 coordinates (taken as float32, as the map reads points), torch.
    np.testing.assert_array_equal(octovk.key_to_coord(0.1, (32768, 32767, 32769)),
                                  np.float32([0.05, -0.05, 0.15]))
    assert octovk.coord_to_key(0.1, [0.0, -0.0001, 3276.75]).tolist() == [32768, 32767, 65535]
    t = octovk.key_to_coord(0.1, torch.from_numpy(keys.astype(np.int32)))
    assert isinstance(t, torch.Tensor) and torch.equal(t, torch.from_numpy(centres))
    tk = octovk.coord_to_key(0.1, torch.from_numpy(centres))
    assert tk.dtype == torch.int32 and (tk.numpy() == keys).all()
    with pytest.raises(ValueError, match=r"keys: key 1 holds 65536; a key is 0 to 65535"):
        octovk.key_to_coord(0.1, np.array([[0, 0, 0], [65536, 0, 0]]))
    with pytest.raises(TypeError, match=r"keys: expected integer keys .* got float32"):
        octovk.key_to_coord(0.1, centres)
    with pytest.raises(ValueError, match=r"coords: point 1 \(nan, 0, 0\) is NaN or outside"):
        octovk.coord_to_key(0.1, np.float32([[0, 0, 0], [np.nan, 0, 0]]))
    with pytest.raises(ValueError, match=r"coords: point 0 .* outside the key range"):
        octovk.coord_to_key(0.1, [4000.0, 0, 0])
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 3\).*got shape \(2, 2\)"):
        octovk.coord_to_key(0.1, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="resolution"):
        octovk.key_to_coord(0.0, keys)


def test_lavapipe_threads_are_chosen_unless_the_user_sets_them():
    # Issue 30.6: unset at import, LP_NUM_THREADS becomes 0 (a scan is many small passes, which
    # lavapipe's worker threads slow down); the user's setting wins. A fresh interpreter each.
    import subprocess
    import sys

    code = "import octovk; print(octovk.cpu_driver_threads())"
    unset = {k: v for k, v in os.environ.items() if k != "LP_NUM_THREADS"}
    chosen = subprocess.run([sys.executable, "-c", code], env=unset, capture_output=True, text=True)
    assert chosen.returncode == 0, chosen.stderr
    assert chosen.stdout.strip() == "('0', True)"
    given = subprocess.run([sys.executable, "-c", code], env={**unset, "LP_NUM_THREADS": "3"},
                           capture_output=True, text=True)
    assert given.returncode == 0, given.stderr
    assert given.stdout.strip() == "('3', False)"


def test_a_map_larger_than_its_cap_spills_tiles_and_writes_the_whole_map(context, tmp_path):
    def sphere(centre, n=400, radius=0.6):
        d = np.random.default_rng(7).normal(size=(n, 3))
        d = d / np.linalg.norm(d, axis=1, keepdims=True) * radius
        return np.ascontiguousarray((d + centre).astype(np.float32))

    places = [np.float32([20.0 * k, 0, 0]) for k in range(10)] + \
        [np.float32([20.0 * k, 0, 0]) for k in (8, 4, 0)]
    whole = octovk.Map(0.1)
    probe = octovk.Map(0.1)
    probe.insert_point_cloud(sphere(places[0]), places[0])
    cap = probe.device_bytes() + probe.device_bytes_by_use().pool // 8
    capped = octovk.Map(0.1, max_device_bytes=cap)
    capped.spill_tiles()
    most = 0
    for p in places:
        whole.insert_point_cloud(sphere(p), p)
        capped.insert_point_cloud(sphere(p), p)
        most = max(most, capped.spilled_tiles())
        assert capped.device_bytes() <= cap
    assert most > 0
    assert capped.node_count() == whole.node_count()
    whole.write(tmp_path / "whole.bt")
    capped.write(tmp_path / "capped.bt")
    assert (tmp_path / "whole.bt").read_bytes() == (tmp_path / "capped.bt").read_bytes()
    if capped.spilled_tiles() > 0:
        with pytest.raises(ValueError) as e:
            capped.search(sphere(places[0]))
        assert "spilled" in str(e.value)
