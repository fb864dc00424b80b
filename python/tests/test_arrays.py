"""Arrays in and out: inputs read in place (numpy, torch CPU tensors, any __dlpack__ object),
wrong dtype / shape / strides / device refused with the argument named, outputs shared with
numpy and torch through the buffer protocol and DLPack, and caller-provided out= arrays."""

import numpy as np
import pytest
import torch

import octovk


@pytest.fixture
def scanned(context):
    m = octovk.Map(0.1)
    rng = np.random.default_rng(2)
    d = rng.normal(size=(500, 3)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    points = np.ascontiguousarray(d * np.float32(1.5))
    m.insert_point_cloud(points, (0, 0, 0))
    return m, points


class OnlyDlpack:
    """An array reachable only through __dlpack__ (no buffer protocol), as other libraries are."""

    def __init__(self, array, device=(1, 0)):
        self.array, self.device = array, device

    def __dlpack__(self, stream=None):
        return self.array.__dlpack__()

    def __dlpack_device__(self):
        return self.device


# ---- read in place ----

def test_points_are_read_in_place_from_numpy_torch_and_dlpack(scanned):
    m, points = scanned
    m.insert_point_cloud(points, (0, 0, 0))
    assert octovk._last_input_address() == points.ctypes.data
    t = torch.from_numpy(points.copy())
    m.insert_point_cloud(t, (0, 0, 0))
    assert octovk._last_input_address() == t.data_ptr()
    m.submit_point_cloud(t, (0, 0, 0))
    assert octovk._last_input_address() == t.data_ptr()
    m.flush()
    wrapped = OnlyDlpack(points)
    m.search(wrapped)
    assert octovk._last_input_address() == points.ctypes.data
    # A view that starts inside another array, still C-contiguous: its own first byte.
    tail = points[100:]
    m.search(tail)
    assert octovk._last_input_address() == tail.ctypes.data


def test_depth_images_are_read_in_place(context):
    m = octovk.Map(0.1)
    # torch 1.13 has no uint16: a numpy uint16 image, and a float32 tensor in metres.
    depth = np.full((12, 16), 3000, np.uint16)
    stats = m.insert_depth_image(depth, 10.0, 10.0, 7.5, 5.5, 5000.0)
    assert octovk._last_input_address() == depth.ctypes.data
    assert stats.points == 12 * 16
    metres = torch.full((12, 16), 0.6, dtype=torch.float32)
    m.insert_depth_image(metres, 10.0, 10.0, 7.5, 5.5, 1.0, pose=np.eye(4))
    assert octovk._last_input_address() == metres.data_ptr()


def test_results_equal_for_numpy_torch_and_dlpack_inputs(scanned):
    m, points = scanned
    a = m.search(points)
    b = m.search(torch.from_numpy(points))
    c = m.search(OnlyDlpack(points))
    for x, y, z in zip(a, b, c):
        np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(x, z)


# ---- refused inputs name the argument and what they got ----

@pytest.mark.parametrize("bad,error,words", [
    (np.zeros((4, 3), np.float64), TypeError, ["points", "float32", "got a float64 array of shape (4, 3)"]),
    (np.zeros((4, 3), np.int32), TypeError, ["points", "got a int32 array"]),
    (np.zeros((4, 3), np.dtype(">f4")), TypeError, ["points", "byte-swapped float32"]),
    (torch.zeros((4, 3), dtype=torch.float64), TypeError, ["points", "float64"]),
    (torch.zeros((4, 3), dtype=torch.float16), TypeError, ["points", "float16"]),
    (np.zeros((4, 5), np.float32), ValueError,
     ["points", "shape (N, 3), (H, W, 3) or (N, 4) with x, y, z first", "got shape (4, 5)"]),
    (np.zeros((4, 4), np.float32), ValueError,
     ["points: (N, 4) points are read as x, y, z", "np.ascontiguousarray(points[:, :3])",
      "or pass copy=True"]),
    (np.zeros((3,), np.float32), ValueError, ["points", "got shape (3,)"]),
    (np.zeros((2, 4, 4), np.float32), ValueError, ["points", "got shape (2, 4, 4)"]),
    (np.zeros((2, 4, 3), np.float32)[:, ::2], ValueError, ["points", "not C-contiguous"]),
    (np.zeros((8, 3), np.float32)[::2], ValueError, ["points", "not C-contiguous", "strides (24, 4)"]),
    (np.zeros((3, 4), np.float32).T, ValueError, ["points", "not C-contiguous"]),
    (torch.zeros((3, 4)).t(), ValueError, ["points", "not C-contiguous"]),
    ([[0.0, 0.0, 1.0]], TypeError, ["points", "buffer protocol or __dlpack__", "got list"]),
    ("points", TypeError, ["points", "got str"]),
])
def test_wrong_points_are_refused_naming_the_argument(scanned, bad, error, words):
    m, _ = scanned
    nodes = m.node_count()
    with pytest.raises(error) as raised:
        m.insert_point_cloud(bad, (0, 0, 0))
    for w in words:
        assert w in str(raised.value)
    with pytest.raises(error):
        m.search(bad)
    assert m.node_count() == nodes


def test_fixes_are_spelt_in_the_callers_library(scanned):
    m, points = scanned
    param = torch.nn.Parameter(torch.zeros((4, 3), dtype=torch.float64), requires_grad=False)
    for bad, fix, foreign in [
            (torch.zeros((4, 3), dtype=torch.float64), "tensor.float()", "astype"),
            (param, "tensor.float()", "astype"),
            (torch.zeros((3, 4)).t(), "(pass tensor.contiguous()", "ascontiguousarray"),
            (np.zeros((4, 3)), "with .astype(np.float32)", "tensor"),
            (np.zeros((3, 4), np.float32).T, "(pass np.ascontiguousarray(points)", "tensor")]:
        with pytest.raises((TypeError, ValueError)) as raised:
            m.search(bad)
        assert fix in str(raised.value) and foreign not in str(raised.value), str(raised.value)
    n = len(points)
    with pytest.raises(TypeError, match=r"out\[0\] \(state\): .*tensor\.byte\(\)"):
        m.search(points, out=(torch.empty(n), torch.empty(n), torch.empty(n, dtype=torch.uint8)))


def test_strided_points_are_copied_only_when_the_caller_says_copy(scanned, tmp_path):
    m, points = scanned
    p4 = np.hstack([points, np.ones((len(points), 1), np.float32)])  # x, y, z, intensity
    xyz = p4[:, :3]
    with pytest.raises(ValueError, match=r"strides \(16, 4\).*not C-contiguous.*, or copy=True\)"):
        m.search(xyz)
    with pytest.raises(ValueError) as raised:  # no copy offered for an out array
        m.search(points, out=(np.empty(len(points), np.uint8),
                              np.empty(2 * len(points), np.float32)[::2],
                              np.empty(len(points), np.uint8)))
    assert "(pass np.ascontiguousarray(out[1] (log_odds)))" in str(raised.value)
    want = m.search(points)
    for strided in (xyz, torch.from_numpy(p4)[:, :3]):
        for got, w in zip(m.search(strided, copy=True), want):
            np.testing.assert_array_equal(got, w)
        assert octovk._last_input_address() != p4.ctypes.data  # a copy was read
    np.testing.assert_array_equal(m.search(points[::-1], copy=True)[1], want[1][::-1])
    raw = np.zeros(points.nbytes + 1, np.uint8)
    misaligned = raw[1:].view(np.float32).reshape(points.shape)
    misaligned[:] = points
    np.testing.assert_array_equal(m.search(misaligned, copy=True)[1], want[1])
    # Read in place where it can be, and the type is never converted.
    m.search(points, copy=True)
    assert octovk._last_input_address() == points.ctypes.data
    with pytest.raises(TypeError, match="float64"):
        m.search(p4.astype(np.float64)[:, :3], copy=True)
    # Every call taking points: the answers of the contiguous points.
    np.testing.assert_array_equal(m.cast_rays(xyz, xyz, copy=True)[1],
                                  m.cast_rays(points, points)[1])
    for name, p, copy in (("a", xyz, True), ("b", points, False)):
        built = octovk.Map(0.1)
        built.insert_point_cloud(p, (0, 0, 0), copy=copy)
        built.submit_point_cloud(p[::2], (0, 0, 0), copy=True)
        built.flush()
        built.write(tmp_path / f"{name}.ot")
    assert (tmp_path / "a.ot").read_bytes() == (tmp_path / "b.ot").read_bytes()
    field = octovk.DistanceField(m, (-1, -1, -1), (1, 1, 1))
    np.testing.assert_array_equal(field.distances(xyz, copy=True)[0], field.distances(points)[0])
    spheres = np.hstack([points, np.full((len(points), 2), 0.1, np.float32)])[:, :4]
    np.testing.assert_array_equal(field.clearances(spheres, copy=True)[0],
                                  field.clearances(np.ascontiguousarray(spheres))[0])


def test_misaligned_and_foreign_device_arrays_are_refused(scanned):
    m, _ = scanned
    raw = np.zeros(4 * 3 * 4 + 1, np.uint8)
    misaligned = raw[1:].view(np.float32).reshape(4, 3)
    with pytest.raises(ValueError, match="points: the array's data is not aligned"):
        m.insert_point_cloud(misaligned, (0, 0, 0))
    cuda = OnlyDlpack(np.zeros((4, 3), np.float32), device=(2, 1))
    with pytest.raises(ValueError, match=r"points: the tensor is on cuda:1 .*host memory only"):
        m.insert_point_cloud(cuda, (0, 0, 0))
    with pytest.raises(ValueError, match=r"directions: the tensor is on cuda:1"):
        m.cast_rays((0, 0, 0), cuda)


def test_lazily_negated_tensors_are_refused_not_read_unnegated(scanned):
    # DLPack carries no sign bit: torch exports a negated view's memory, which holds -x.
    m, points = scanned
    negated = torch.from_numpy(-points)._neg_view()
    assert negated.is_neg() and torch.equal(negated, torch.from_numpy(points))
    nodes = m.node_count()
    for call in (lambda p: m.insert_point_cloud(p, (0, 0, 0)),
                 lambda p: m.submit_point_cloud(p, (0, 0, 0)), m.search,
                 lambda p: m.cast_rays(p, p)):
        with pytest.raises(ValueError, match=r"points|origins|directions") as raised:
            call(negated)
        assert "negated" in str(raised.value) and "resolve_neg()" in str(raised.value)
    m.flush()
    assert m.node_count() == nodes
    # The public way to such a view: the imaginary part of a conjugated complex tensor.
    imag = torch.zeros((4, 6), dtype=torch.complex64).conj().imag
    assert imag.is_neg()
    with pytest.raises(ValueError, match="resolve_neg"):
        m.search(imag)
    with pytest.raises(ValueError, match=r"depth: .*negated.*resolve_neg"):
        m.insert_depth_image(torch.ones((4, 4))._neg_view(), 1, 1, 1, 1, 1)
    n = len(points)
    outs = (torch.empty(n, dtype=torch.uint8), torch.empty(n)._neg_view(),
            torch.empty(n, dtype=torch.uint8))
    with pytest.raises(ValueError, match=r"out\[1\] \(log_odds\): .*resolve_neg"):
        m.search(points, out=outs)
    # Resolved, the tensor reads as it shows: the same answers as the numpy points.
    for got, want in zip(m.search(negated.resolve_neg()), m.search(points)):
        np.testing.assert_array_equal(got, want)
    # A conjugated view is refused the same way, before its complex type is.
    with pytest.raises(ValueError, match="resolve_conj"):
        m.search(torch.zeros((4, 3), dtype=torch.complex64).conj())


def test_wrong_depth_images_are_refused(context):
    m = octovk.Map(0.1)
    with pytest.raises(TypeError, match=r"depth: expected a C-contiguous float32 or uint16 array"
                                        r" of shape \(H, W\) or \(1, H, W\), got a int16 array"):
        m.insert_depth_image(np.zeros((4, 4), np.int16), 1, 1, 1, 1, 1)
    with pytest.raises(ValueError, match=r"depth: .*got shape \(4, 4, 1\)"):
        m.insert_depth_image(np.zeros((4, 4, 1), np.uint16), 1, 1, 1, 1, 1)
    with pytest.raises(ValueError, match=r"depth: .*got shape \(2, 4, 4\)"):
        m.insert_depth_image(np.zeros((2, 4, 4), np.uint16), 1, 1, 1, 1, 1)
    with pytest.raises(octovk.InvalidArgumentError, match="depth_scale"):
        m.insert_depth_image(np.ones((4, 4), np.uint16), 1, 1, 1, 1, -1)


def test_wrong_vectors_and_poses_are_refused(scanned):
    m, points = scanned
    for bad in ((1, 2), "abc", None, np.zeros((1, 3))):
        with pytest.raises(ValueError, match="origin: expected 3 numbers"):
            m.insert_point_cloud(points, bad)
    with pytest.raises(ValueError, match="pose: the 4x4 matrix is not a rigid transform"):
        m.insert_point_cloud(points, (0, 0, 0), pose=np.diag([2.0, 1, 1, 1]))
    with pytest.raises(ValueError, match="pose: expected None, an octovk.Pose"):
        m.insert_point_cloud(points, (0, 0, 0), pose=np.eye(3))
    with pytest.raises(ValueError, match="pose: the quaternion .* has norm 2"):
        m.insert_point_cloud(points, (0, 0, 0), pose=((0, 0, 0), (0, 0, 0, 2)))


def test_poses_in_every_form_give_the_same_map(context, tmp_path):
    points = np.random.default_rng(4).uniform(-1, 1, (300, 3)).astype(np.float32) + np.float32([2, 0, 0])
    q = np.array([0.0, 0.0, np.sin(0.3), np.cos(0.3)])  # x y z w: 0.6 rad about z
    t = np.array([0.5, -0.25, 0.1])
    pose = octovk.Pose(t, q)
    forms = [pose, (t, q), (list(t), tuple(q)), (torch.tensor(t), torch.tensor(q)),
             octovk.Pose.from_matrix(pose.matrix())]
    written = []
    for i, form in enumerate(forms):
        m = octovk.Map(0.1)
        m.insert_point_cloud(points, (0, 0, 0), pose=form)
        m.write(tmp_path / f"{i}.ot")
        written.append((tmp_path / f"{i}.ot").read_bytes())
    assert all(w == written[0] for w in written[:4])
    # From a matrix the quaternion is recomputed (not bit-equal): the same map up to rounding.
    np.testing.assert_allclose(forms[4].rotation, pose.rotation, atol=1e-6)
    np.testing.assert_allclose(pose.transform((1, 0, 0)), pose.matrix()[:3] @ [1, 0, 0, 1],
                               atol=1e-6)
    np.testing.assert_allclose(pose.inverse().transform(pose.transform((1, 2, 3))), (1, 2, 3),
                               atol=1e-5)


# ---- results: owned arrays shared through the buffer protocol and DLPack ----

def test_results_share_memory_with_numpy_and_torch(scanned):
    m, points = scanned
    state, log_odds, depth = m.search(points)
    hit, end = m.cast_rays((0, 0, 0), points)
    centers, sizes, leaf_log_odds = m.leaves()
    for result in (state, log_odds, depth, hit, end, centers, sizes, leaf_log_odds):
        assert isinstance(result, np.ndarray)
        assert np.asarray(result).ctypes.data == result.ctypes.data
        assert np.from_dlpack(result).ctypes.data == result.ctypes.data
        shared = torch.from_dlpack(result)
        assert shared.data_ptr() == result.ctypes.data
        np.testing.assert_array_equal(shared.numpy(), result)
        assert memoryview(result).nbytes == result.nbytes
    # The leaves are views of one buffer the arrays keep alive.
    leaves = m.leaves()
    assert leaves[0].base is not None and leaves[1].base is not None
    del m
    assert np.isfinite(leaves[0]).all() and (leaves[1] > 0).all()


def test_out_arrays_are_written_in_place(scanned):
    m, points = scanned
    n = len(points)
    want = m.search(points)
    outs = (np.empty(n, np.uint8), np.empty(n, np.float32), np.empty(n, np.uint8))
    got = m.search(points, out=outs)
    assert all(g is o for g, o in zip(got, outs))
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
    # torch tensors as out, through DLPack.
    touts = (torch.empty(n, dtype=torch.uint8), torch.empty(n), torch.empty(n, dtype=torch.uint8))
    m.search(torch.from_numpy(points), out=touts)
    for g, w in zip(touts, want):
        np.testing.assert_array_equal(g.numpy(), w)
    hit_want, end_want = m.cast_rays((0, 0, 0), points, max_range_m=1.0)
    hit, end = np.empty(n, np.uint8), np.empty((n, 3), np.float32)
    m.cast_rays((0, 0, 0), points, max_range_m=1.0, out=(hit, end))
    np.testing.assert_array_equal(hit, hit_want)
    np.testing.assert_array_equal(end, end_want)


def test_wrong_out_arrays_are_refused(scanned):
    m, points = scanned
    n = len(points)
    good = [np.empty(n, np.uint8), np.empty(n, np.float32), np.empty(n, np.uint8)]
    with pytest.raises(ValueError, match=r"out\[1\] \(log_odds\): .*got shape \(3,\)"):
        m.search(points, out=(good[0], np.empty(3, np.float32), good[2]))
    with pytest.raises(TypeError, match=r"out\[0\] \(state\): .*uint8.*got a int64 array"):
        m.search(points, out=(np.empty(n, np.int64), good[1], good[2]))
    readonly = np.empty(n, np.uint8)
    readonly.flags.writeable = False
    with pytest.raises(ValueError, match=r"out\[2\] \(depth\): the array is read-only"):
        m.search(points, out=(good[0], good[1], readonly))
    with pytest.raises(ValueError, match="out: expected a tuple"):
        m.search(points, out=good[:2])
    with pytest.raises(ValueError, match=r"origins: .*got shape \(2, 3\)"):
        m.cast_rays(np.zeros((2, 3), np.float32), points)


def test_empty_inputs(scanned):
    m, _ = scanned
    nodes = m.node_count()
    empty = np.zeros((0, 3), np.float32)
    stats = m.insert_point_cloud(empty, (0, 0, 0))
    assert stats.points == 0 and stats.nodes == nodes
    state, log_odds, depth = m.search(empty)
    assert state.shape == (0,) and log_odds.dtype == np.float32 and depth.dtype == np.uint8
    hit, end = m.cast_rays(empty, empty)
    assert hit.shape == (0,) and end.shape == (0, 3)


# ---- the shapes perception code has ----

def same_leaves(a, b):
    """The two maps hold the same leaves (centres and log-odds), in any order."""
    rows = [np.column_stack([m.leaves()[0], m.leaves()[2]]) for m in (a, b)]
    rows = [r[np.lexsort(r.T)] for r in rows]
    return rows[0].shape == rows[1].shape and np.array_equal(rows[0], rows[1])


def test_organised_clouds_and_channel_first_depth_are_read_in_place(scanned):
    m, points = scanned
    cloud = points[:480].reshape(20, 24, 3)  # (H, W, 3), C-contiguous: H * W points
    want = m.search(points[:480])
    got = m.search(cloud)
    assert octovk._last_input_address() == cloud.ctypes.data
    for g, w in zip(got, want):  # one result per point, in the cloud's shape
        assert g.shape == cloud.shape[:2] + w.shape[1:]
        np.testing.assert_array_equal(g.reshape(w.shape), w)
    hit, end = m.cast_rays((0, 0, 0), cloud)
    assert hit.shape == (20, 24) and end.shape == (20, 24, 3)
    np.testing.assert_array_equal(end.reshape(-1, 3), m.cast_rays((0, 0, 0), points[:480])[1])
    np.testing.assert_array_equal(m.cast_rays(cloud * 0, cloud)[1], end)  # origins per ray
    with pytest.raises(ValueError, match=r"origins: expected one origin per direction"):
        m.cast_rays(points[:480], cloud)
    a, b = octovk.Map(0.1), octovk.Map(0.1)
    a.insert_point_cloud(cloud, (0, 0, 0))
    b.insert_point_cloud(points[:480], (0, 0, 0))
    assert a.node_count() == b.node_count() and same_leaves(a, b)
    # A depth image with its one channel first, as torch's (C, H, W): read in place.
    depth = np.full((1, 12, 16), 3000, np.uint16)
    stats = m.insert_depth_image(depth, 10.0, 10.0, 7.5, 5.5, 5000.0)
    assert octovk._last_input_address() == depth.ctypes.data and stats.points == 12 * 16
    metres = torch.full((1, 12, 16), 0.6)
    m.submit_depth_image(metres, 10.0, 10.0, 7.5, 5.5, 1.0)
    assert octovk._last_input_address() == metres.data_ptr()
    m.flush()


def test_points_with_intensity_are_read_as_xyz_with_copy(scanned):
    m, points = scanned
    p4 = np.hstack([points, np.arange(len(points), dtype=np.float32)[:, None]])  # x y z i
    for given in (p4, torch.from_numpy(p4)):
        with pytest.raises(ValueError, match=r"points: \(N, 4\) points are read as x, y, z, their "
                                             r"first three columns.*or pass copy=True"):
            m.search(given)
    with pytest.raises(ValueError, match=r"points\[:, :3\]\.contiguous\(\)"):
        m.insert_point_cloud(torch.from_numpy(p4), (0, 0, 0))
    want = m.search(points)
    for given in (p4, torch.from_numpy(p4)):
        for g, w in zip(m.search(given, copy=True), want):
            np.testing.assert_array_equal(np.asarray(g), w)
    a, b = octovk.Map(0.1), octovk.Map(0.1)
    a.insert_point_cloud(p4, (0, 0, 0), copy=True)
    b.insert_point_cloud(points, (0, 0, 0))
    assert a.node_count() == b.node_count() and same_leaves(a, b)
    one = p4[:1]  # a single row is packed xyz: read in place
    m.search(one)
    assert octovk._last_input_address() == one.ctypes.data


def test_queries_return_tensors_for_tensors(scanned):
    m, points = scanned
    t = torch.from_numpy(points)
    state, log_odds, depth = m.search(t)
    assert all(isinstance(r, torch.Tensor) for r in (state, log_odds, depth))
    assert (state.dtype, log_odds.dtype, tuple(log_odds.shape)) == (torch.uint8, torch.float32,
                                                                    (len(points),))
    for got, want in zip((state, log_odds, depth), m.search(points)):
        assert isinstance(want, np.ndarray)
        np.testing.assert_array_equal(got.numpy(), want)
    hit, end = m.cast_rays((0, 0, 0), t, max_range_m=1.0)
    assert isinstance(hit, torch.Tensor) and tuple(end.shape) == (len(points), 3)
    np.testing.assert_array_equal(end.numpy(), m.cast_rays((0, 0, 0), points, max_range_m=1.0)[1])
    assert (state == octovk.CellState.OCCUPIED).any()
    # out= arrays come back as they were given.
    outs = (np.empty(len(points), np.uint8), np.empty(len(points), np.float32),
            np.empty(len(points), np.uint8))
    assert all(g is o for g, o in zip(m.search(t, out=outs), outs))
