"""Misuse raises a Python error and touches nothing: paths with a NUL byte (which the C library
would cut short, reaching another file), and objects made by __new__ whose __init__ never ran
(which pybind11 would hand to C++ as raw memory). The crashing kind runs in a subprocess, so that
a regression fails its test instead of killing pytest."""

import inspect
import os
import pathlib
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import octovk


def test_paths_with_a_nul_byte_are_refused_everywhere(context, tmp_path):
    m = octovk.Map(0.1)
    m.insert_point_cloud(np.array([[1, 0, 0]], np.float32), (0, 0, 0))
    notes = tmp_path / "notes.txt"
    notes.write_text("keep me")
    (tmp_path / "map.bt").write_bytes(b"")  # would be read if the NUL cut the name
    calls = {
        "Map.write": lambda p: m.write(p),
        "Map.read": lambda p: octovk.Map.read(p),
        "read_scan_graph": octovk.read_scan_graph,
        "read_depth_png": octovk.read_depth_png,
        "read_tum_sequence": octovk.read_tum_sequence,
    }
    for name, call in calls.items():
        for bad in (f"{notes}\x00.bt", f"{tmp_path}/map.bt\x00".encode(),
                    pathlib.Path(f"{tmp_path}\x00")):
            with pytest.raises(ValueError) as raised:
                call(bad)
            assert "NUL byte" in str(raised.value), (name, str(raised.value))
            assert not isinstance(raised.value, octovk.Error), name
    assert notes.read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.bt", "notes.txt"]
    assert m.node_count() > 0  # the map works on


def test_bytes_and_pathlike_paths_name_the_file_they_spell(context, tmp_path):
    # os.fsencode, as open() takes them: a bytes path is the file, not the text "b'...'".
    m = octovk.Map(0.1)
    m.insert_point_cloud(np.array([[1, 0, 0]], np.float32), (0, 0, 0))
    m.write(os.fsencode(tmp_path / "a.bt"))
    m.write(tmp_path / "b.ot")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bt", "b.ot"]
    assert octovk.Map.read(os.fsencode(tmp_path / "b.ot")).node_count() == m.node_count()


# What each method of a bound class needs to get past pybind11's own argument checks; every
# method and property of every class must then refuse an uninitialised self.
ARGUMENTS = {
    "write": ("/nonexistent/x.bt",),
    "insert_point_cloud": ("P", (0, 0, 0)),
    "submit_point_cloud": ("P", (0, 0, 0)),
    "insert_depth_image": ("D", 1.0, 1.0, 1.0, 1.0, 1.0),
    "submit_depth_image": ("D", 1.0, 1.0, 1.0, 1.0, 1.0),
    "finished": (1,),
    "search": ("P",),
    "colors": ("P",),
    "stamps": ("P",),
    "degrade_outdated": (0,),
    "cast_rays": ((0, 0, 0), "P"),
    "leaves_in_box": ((0, 0, 0), (1, 1, 1)),
    "clear_box": ((0, 0, 0), (1, 1, 1)),
    "keep_box": ((0, 0, 0), (1, 1, 1)),
    "enable_change_detection": (True,),
    "distances": ("P",),
    "clearances": ("S",),
    "torch_distances": ("P",),
    "transform": ((1, 2, 3),),
    "__eq__": ("E",),  # an enum compares only with its own type
    "__ne__": ("E",),
}
# Called on the class, not an instance; __setstate__ initialises an instance, as __init__ does.
NOT_ON_SELF = {"__init__", "__new__", "__setstate__"}

SCRIPT = textwrap.dedent("""
    import inspect, sys
    import numpy as np
    import octovk
    from test_misuse import ARGUMENTS, NOT_ON_SELF, members

    values = {"P": np.zeros((2, 3), np.float32), "S": np.zeros((2, 4), np.float32),
              "D": np.zeros((2, 2), np.float32)}
    checked = 0

    def refuses(label, call):
        global checked
        print(label, flush=True)  # the last line names the call that crashed
        try:
            call()
        except TypeError as e:
            assert "never initialised" in str(e), (label, str(e))
            checked += 1
            return
        raise AssertionError(f"{label}: no error")

    for cls in members(octovk):
        blank = cls.__new__(cls)
        for name, kind in members(cls):
            if kind == "property":
                refuses(f"{cls.__name__}.{name}", lambda: getattr(blank, name))
            else:
                own = {"E": getattr(cls, "__members__", {None: None}).popitem()[1]}
                args = [{**values, **own}.get(a, a) if isinstance(a, str) else a
                        for a in ARGUMENTS.get(name, ())]
                refuses(f"{cls.__name__}.{name}()", lambda: getattr(blank, name)(*args))

    # Uninitialised objects as arguments.
    points = values["P"]
    refuses("Map(context=)", lambda: octovk.Map(context=octovk.Context.__new__(octovk.Context)))
    refuses("Map.read(context=)", lambda: octovk.Map.read(
        "x.bt", context=octovk.Context.__new__(octovk.Context)))
    refuses("Map(cast_ray_backend=)", lambda: octovk.Map(
        cast_ray_backend=octovk.CastRayBackend.__new__(octovk.CastRayBackend)))
    refuses("DistanceField(map)", lambda: octovk.DistanceField(
        octovk.Map.__new__(octovk.Map), (0, 0, 0), (1, 1, 1)))
    blank_pose = octovk.Pose.__new__(octovk.Pose)
    refuses("graph2tree_sensor_origin(pose)", lambda: octovk.graph2tree_sensor_origin(blank_pose))
    m = octovk.Map(0.1)
    refuses("insert_point_cloud(pose=)",
            lambda: m.insert_point_cloud(points, (0, 0, 0), pose=blank_pose))
    refuses("ScanRays == blank", lambda: octovk.ScanRays.WALK == octovk.ScanRays.__new__(
        octovk.ScanRays))
    assert m.node_count() == 0

    # A subclass whose __init__ skips the base's is refused by pybind11 itself.
    class Sub(octovk.Map):
        def __init__(self):
            pass
    try:
        Sub()
        raise AssertionError("Sub() made")
    except TypeError as e:
        assert "__init__() must be called" in str(e)
    refuses("Sub.__new__ node_count()", lambda: Sub.__new__(Sub).node_count())
    print("checked", checked)
""")


def members(owner):
    """The pybind11 classes of the module, or the (name, 'property' / 'method') of a class."""
    if inspect.ismodule(owner):
        return [c for _, c in sorted(vars(owner).items()) if type(c).__name__ == "pybind11_type"]
    out = []
    for name in sorted(dir(owner)):
        attr = inspect.getattr_static(owner, name)
        if type(attr) is property:  # not pybind11's static properties (enums' __members__)
            out.append((name, "property"))
        elif type(attr).__name__ == "instancemethod" and name not in NOT_ON_SELF:
            out.append((name, "method"))  # pybind11's methods, not object's slot wrappers
    return out


def test_uninitialised_objects_raise_instead_of_crashing(context):
    classes = members(octovk)
    assert {octovk.Map, octovk.ColorMap, octovk.StampedMap, octovk.Context,
            octovk.DistanceField, octovk.Pose, octovk.ScanRays} <= set(classes)
    expected = sum(len(members(c)) for c in classes) + 8
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [os.path.dirname(__file__), os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                          env=env, timeout=120)
    assert done.returncode == 0, (
        f"exit {done.returncode}; last call: {done.stdout.strip().splitlines()[-1:]}\n"
        f"{done.stderr[-3000:]}")
    assert done.stdout.strip().splitlines()[-1] == f"checked {expected}", done.stdout[-2000:]


def test_out_of_memory_is_said_in_the_users_words(context):
    """Issue 30.4: a scan, a query batch and a distance field over the Map's max_device_bytes
    each say what needs the memory and what to change, in the module's words: no Vulkan call, no
    source path, no C++ name; the driver's detail, if any, is in Error.detail."""
    import re

    def users_words(error, *mentions):
        message = error.message
        assert str(error) == message
        assert not re.search(r"vk[A-Z]", message), message
        assert "src/" not in message and ".cpp" not in message, message
        assert "MapParams::" not in message and "OccupancyMap::" not in message, message
        for words in mentions:
            assert words in message, message

    m = octovk.Map(0.05, max_device_bytes=3 << 20)
    d = np.random.default_rng(0).normal(size=(4000, 3)).astype(np.float32)
    d = np.ascontiguousarray(d / np.linalg.norm(d, axis=1, keepdims=True) * np.float32(8))
    with pytest.raises(octovk.OutOfDeviceMemoryError) as e:
        m.insert_point_cloud(d, (0, 0, 0))
    users_words(e.value, "the Map's max_device_bytes", "split the scan")
    m.insert_point_cloud(np.float32([[0.5, 0.2, 0.1]]), (0, 0, 0))
    with pytest.raises(octovk.OutOfDeviceMemoryError) as e:
        octovk.DistanceField(m, (-2, -2, -2), (2, 2, 2))
    users_words(e.value, "81 x 81 x 81 cells", "Shrink the box", "the Map's max_device_bytes")
