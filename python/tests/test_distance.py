"""octovk.DistanceField against brute force in numpy: the exact squared distances of every cell of
the box (the minimum over every occupied cell, found with Map.search on each cell's centre), and
batched queries (distance, nearest obstacle, gradient, clearance of spheres) cell for cell. The C++
tests (tests/distance_test.cpp) compare the same field with brute force and dynamicEDT3D."""

import gc
import re
import weakref

import numpy as np
import pytest

import octovk
from conftest import room_scans

RES = 0.1
BOX_MIN = (-1.0, -1.2, -0.5)
BOX_MAX = (1.6, 1.1, 0.4)


def make_map(scans=3):
    m = octovk.Map(RES)
    for points, origin in room_scans(seed=5, scans=scans, points=500):
        m.insert_point_cloud(points, origin)
    return m


def key_of(coords):
    """The finest key of each point's cell (octovk.coord_to_key, as the map reads points), as int64
    so that keys subtract."""
    return octovk.coord_to_key(RES, np.asarray(coords, np.float32)).astype(np.int64)


def centre_of(keys):
    return octovk.key_to_coord(RES, np.asarray(keys))


class Brute:
    """The box's cells, which are obstacles (Map.search), and the brute-force squared distances."""

    def __init__(self, m, unknown_occupied):
        lo, hi = key_of(BOX_MIN), key_of(BOX_MAX)
        self.min_key, self.size = lo, hi - lo + 1
        zz, yy, xx = np.meshgrid(*[np.arange(self.size[a]) for a in (2, 1, 0)], indexing="ij")
        self.cells = np.stack([xx.ravel(), yy.ravel(), zz.ravel()], axis=1)  # index x fastest
        state, _, _ = m.search(np.ascontiguousarray(centre_of(lo + self.cells)))
        occupied = state == int(octovk.CellState.OCCUPIED)
        if unknown_occupied:
            occupied |= state == int(octovk.CellState.UNKNOWN)
        self.occupied = occupied
        sites = self.cells[occupied]
        assert len(sites) > 20, "the test map has too few obstacles in the box"
        d2 = ((self.cells[:, None, :] - sites[None, :, :]) ** 2).sum(axis=2)
        self.squared = d2.min(axis=1).astype(np.uint32)

    def index(self, points):
        """The box index of each point's cell, or -1 outside."""
        # Clipped into the key range: far points (1e9) stay outside the box.
        c = key_of(np.clip(points, -100.0, 100.0)) - self.min_key
        inside = np.all((c >= 0) & (c < self.size), axis=1)
        flat = c[:, 0] + self.size[0] * (c[:, 1] + self.size[1] * c[:, 2])
        return np.where(inside, flat, -1)


@pytest.mark.parametrize("unknown_occupied", [False, True])
def test_every_cell_equals_brute_force(context, unknown_occupied):
    m = make_map()
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance_m=0.7,
                                 treat_unknown_as_occupied=unknown_occupied)
    brute = Brute(m, unknown_occupied)
    assert field.size == tuple(int(s) for s in brute.size)
    assert field.min_key == tuple(int(k) for k in brute.min_key)
    squared, nearest = field.download()
    assert squared.dtype == np.uint32 and squared.shape == tuple(int(s) for s in brute.size[::-1])
    np.testing.assert_array_equal(squared.ravel(), brute.squared)
    # Each nearest cell is an obstacle at that squared distance.
    near = nearest.ravel()
    assert brute.occupied[near].all()
    d2 = ((brute.cells - brute.cells[near]) ** 2).sum(axis=1)
    np.testing.assert_array_equal(d2, brute.squared)
    assert field.treat_unknown_as_occupied == unknown_occupied
    assert field.max_distance_m == pytest.approx(0.7)


def test_queries_equal_brute_force(context):
    m = make_map()
    max_d = 0.5
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance_m=max_d,
                                 treat_unknown_as_occupied=False)
    brute = Brute(m, False)
    _, nearest = field.download()
    nearest = nearest.ravel()
    rng = np.random.default_rng(11)
    points = rng.uniform((-1.5, -1.5, -0.7), (1.8, 1.4, 0.6), (4000, 3)).astype(np.float32)
    points[0] = (np.nan, 0, 0)
    points[1] = (1e9, 0, 0)
    distance, obstacle, gradient, squared = field.distances(points)
    assert distance.shape == (4000,) and obstacle.shape == (4000, 3) and gradient.shape == (4000, 3)
    assert distance.dtype == obstacle.dtype == gradient.dtype == np.float32
    assert squared.dtype == np.uint32
    with np.errstate(invalid="ignore"):
        at = brute.index(np.nan_to_num(points, nan=1e9))
    outside = at < 0
    assert outside[0] and outside[1] and (~outside).sum() > 1000
    assert (distance[outside] == octovk.DistanceField.OUTSIDE).all()
    assert (squared[outside] == octovk.DistanceField.OUTSIDE_CELLS).all()
    assert np.isnan(obstacle[outside]).all() and (gradient[outside] == 0).all()

    inside = ~outside
    cell = at[inside]
    np.testing.assert_array_equal(squared[inside], brute.squared[cell])
    metres = np.sqrt(brute.squared[cell].astype(np.float64)) * RES
    want = np.minimum(metres.astype(np.float32), np.float32(max_d))
    np.testing.assert_array_equal(distance[inside], want)
    site = nearest[cell]
    np.testing.assert_array_equal(obstacle[inside],
                                  centre_of(brute.min_key + brute.cells[site]))
    # The gradient: (cell - obstacle) / sqrt(squared) in cells, zero on an obstacle and where the
    # distance is capped.
    sq = brute.squared[cell].astype(np.float64)
    delta = (brute.cells[cell] - brute.cells[site]).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = (delta / np.sqrt(sq)[:, None]).astype(np.float32)
    flat = (sq == 0) | (metres.astype(np.float32) >= np.float32(max_d))
    unit[flat] = 0
    np.testing.assert_array_equal(gradient[inside], unit)
    assert flat.sum() > 0 and (~flat).sum() > 100

    # Spheres: the clearance is the distance at the centre minus the radius.
    radii = rng.uniform(0, 0.3, len(points)).astype(np.float32)
    spheres = np.ascontiguousarray(np.column_stack([points, radii]), np.float32)
    clearance, obstacle_s, gradient_s, squared_s = field.clearances(spheres)
    np.testing.assert_array_equal(squared_s, squared)
    np.testing.assert_array_equal(clearance[inside], distance[inside] - radii[inside])
    assert (clearance[outside] == octovk.DistanceField.OUTSIDE).all()
    np.testing.assert_array_equal(obstacle_s[inside], obstacle[inside])
    np.testing.assert_array_equal(gradient_s, gradient)
    assert (clearance[inside] < 0).any()  # some spheres reach an obstacle


def test_update_after_scans_equals_a_field_from_scratch(context):
    m = make_map(scans=1)
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance_m=0.8,
                                 treat_unknown_as_occupied=False)
    before, _ = field.download()
    for points, origin in room_scans(seed=9, scans=2, points=400):
        m.submit_point_cloud(points, origin)
    field.update()  # sees the submitted scans
    after, _ = field.download()
    scratch, _ = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance_m=0.8,
                                      treat_unknown_as_occupied=False).download()
    np.testing.assert_array_equal(after, scratch)
    assert not np.array_equal(before, after)
    np.testing.assert_array_equal(after.ravel(), Brute(m, False).squared)
    assert field.last_update_ms >= 0.0


def test_bad_input_and_memory(context):
    m = octovk.Map(RES)
    base = m.device_bytes()
    base_leaf_boxes = m.device_bytes_by_use().leaf_boxes
    with pytest.raises(octovk.InvalidArgumentError, match="inverted"):
        octovk.DistanceField(m, (1, 0, 0), (0, 1, 1))
    with pytest.raises(octovk.InvalidArgumentError, match="NaN"):
        octovk.DistanceField(m, (0, 0, 0), (1, 1, float("nan")))
    with pytest.raises(octovk.InvalidArgumentError, match="max_distance_m"):
        octovk.DistanceField(m, (0, 0, 0), (1, 1, 1), max_distance_m=0.0)
    with pytest.raises(ValueError, match="min"):
        octovk.DistanceField(m, (0, 0), (1, 1, 1))
    assert m.device_bytes() == base
    field = octovk.DistanceField(m, (0, 0, 0), (1, 1, 1))
    assert m.device_bytes_by_use().distance_fields == field.device_bytes() > 0
    with pytest.raises(TypeError, match="points"):
        field.distances(np.zeros((3, 3), np.float64))
    with pytest.raises(ValueError, match="spheres"):
        field.clearances(np.zeros((3, 3), np.float32))
    distance, obstacle, _, squared = field.distances(np.zeros((0, 3), np.float32))
    assert distance.shape == (0,) and obstacle.shape == (0, 3)
    # An empty map: all unknown, so every cell is an obstacle by default; with unknown space
    # free, no obstacle anywhere in the box.
    _, _, _, squared = field.distances(np.full((1, 3), 0.5, np.float32))
    assert squared[0] == 0
    free = octovk.DistanceField(m, (0, 0, 0), (1, 1, 1), treat_unknown_as_occupied=False)
    _, _, _, squared = free.distances(np.full((1, 3), 0.5, np.float32))
    assert squared[0] == octovk.DistanceField.NO_OBSTACLE_CELLS
    with pytest.raises(octovk.InvalidArgumentError, match="give a box"):
        octovk.DistanceField(m)  # an empty map has no bounds
    with pytest.raises(octovk.InvalidArgumentError, match="min is given without max"):
        octovk.DistanceField(m, (0, 0, 0))
    del field, free
    gc.collect()
    # The fields' memory is back; the map made its leaf boxes for them (they stay the map's).
    assert m.device_bytes_by_use().distance_fields == 0
    grown = m.device_bytes_by_use()
    assert m.device_bytes() - grown.leaf_boxes == base - base_leaf_boxes


def test_max_distance_m_and_its_old_name(context):
    """max_distance_m, C++'s DistanceFieldOptions::max_distance_m; max_distance still works for
    one release, with a DeprecationWarning (the keyword and the property)."""
    m = make_map(scans=1)
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance_m=0.4)
    assert field.max_distance_m == pytest.approx(0.4)
    with pytest.warns(DeprecationWarning, match="max_distance is deprecated: name it "):
        old = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance=0.4)
    with pytest.warns(DeprecationWarning, match="max_distance_m"):
        assert old.max_distance == pytest.approx(0.4)
    np.testing.assert_array_equal(old.download()[0], field.download()[0])


def test_points_as_map_search_takes_them_and_torch_in_torch_out(context):
    """distances reads (N, 3), (H, W, 3) and (N, 4) with x, y, z first (copy=True), as Map.search;
    distances and clearances answer torch tensors for torch inputs."""
    import torch
    m = make_map(scans=1)
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, treat_unknown_as_occupied=False)
    rng = np.random.default_rng(3)
    points = rng.uniform(BOX_MIN, BOX_MAX, (12, 3)).astype(np.float32)
    want = field.distances(points)
    organised = field.distances(points.reshape(3, 4, 3))
    for got, w, shape in zip(organised, want, ((3, 4), (3, 4, 3), (3, 4, 3), (3, 4))):
        assert got.shape == shape
        np.testing.assert_array_equal(got.reshape(w.shape), w)
    p4 = np.hstack([points, np.ones((len(points), 1), np.float32)])  # x, y, z, intensity
    with pytest.raises(ValueError, match="copy"):
        field.distances(p4)
    for got, w in zip(field.distances(p4, copy=True), want):
        np.testing.assert_array_equal(got, w)
    t = field.distances(torch.from_numpy(points))
    assert all(isinstance(x, torch.Tensor) for x in t)
    assert t[3].dtype == torch.int64  # squared_cells: this torch has no uint32
    for got, w in zip(t, want):
        np.testing.assert_array_equal(got.numpy(), w)
    spheres = np.hstack([points, np.full((len(points), 1), 0.05, np.float32)])
    c = field.clearances(torch.from_numpy(spheres))
    assert all(isinstance(x, torch.Tensor) for x in c)
    for got, w in zip(c, field.clearances(spheres)):
        np.testing.assert_array_equal(got.numpy(), w)


def test_the_field_keeps_its_map_alive(context):
    m = make_map(scans=1)
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX)
    assert field.map is m
    ref = weakref.ref(m)
    del m
    gc.collect()
    assert ref() is not None
    _, _, _, squared = field.distances(np.zeros((1, 3), np.float32))
    assert squared.shape == (1,)
    del field
    gc.collect()
    assert ref() is None


def test_unknown_space_is_an_obstacle_by_default(context):
    """Issue 30.5: space the map never saw is no clearance unless the caller says so."""
    m = make_map()
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance_m=0.7)
    assert field.treat_unknown_as_occupied
    squared, _ = field.download()
    np.testing.assert_array_equal(squared.ravel(), Brute(m, True).squared)
    brute = Brute(m, False)
    centres = np.ascontiguousarray(centre_of(brute.min_key + brute.cells))
    state, _, _ = m.search(centres)
    unseen = centres[state == int(octovk.CellState.UNKNOWN)]
    assert len(unseen) > 100, "the test map should leave unknown cells in the box"
    assert (field.distances(unseen)[0] == 0.0).all()
    optimistic = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance_m=0.7,
                                      treat_unknown_as_occupied=False)
    assert (optimistic.distances(unseen)[0] > 0.0).any()


def test_the_default_box_is_the_maps_bounds_and_one_cell_around(context):
    m = make_map(scans=1)
    field = octovk.DistanceField(m, max_distance_m=0.5)
    centres, sizes, _ = m.leaves()
    half = (sizes[:, None].astype(np.float64) - RES) / 2
    lo = np.floor((centres - half) / RES).astype(np.int64).min(axis=0) + 32768 - 1
    hi = np.floor((centres + half) / RES).astype(np.int64).max(axis=0) + 32768 + 1
    assert field.min_key == tuple(int(k) for k in lo)
    assert field.size == tuple(int(n) for n in hi - lo + 1)
    # The ring around the bounds is unknown: obstacles by default.
    squared, _ = field.download()
    assert (squared[0] == 0).all() and (squared[:, :, -1] == 0).all()


def no_internals(message):
    """An error text in the user's words: no Vulkan call, no source path, no C++ names."""
    assert not re.search(r"vk[A-Z]", message), message
    assert "src/" not in message and ".cpp" not in message, message
    assert "MapParams::" not in message and "split the scan" not in message, message


def test_out_of_memory_names_the_box_the_bytes_and_what_to_change(context):
    """Issue 30.4, with a cap and without one."""
    m = make_map(scans=1)
    capped = octovk.Map(RES, max_device_bytes=m.device_bytes() + (1 << 20))
    capped.insert_point_cloud(np.float32([[0.5, 0.2, 0.1]]), (0, 0, 0))
    with pytest.raises(octovk.OutOfDeviceMemoryError) as e:
        octovk.DistanceField(capped, (0, 0, 0), (6, 6, 6))
    no_internals(e.value.message)
    for words in ("61 x 61 x 61 cells", "MiB", "Shrink the box", "raise the Map's max_device_bytes"):
        assert words in e.value.message, e.value.message
    assert e.value.detail == ""  # the cap refused it, not the driver
    with pytest.raises(octovk.OutOfDeviceMemoryError) as e:
        octovk.DistanceField(m, (-100, -100, -10), (100, 100, 10))
    no_internals(e.value.message)
    for words in ("2001 x 2001 x 201 cells", "GiB", "the device has", "Shrink the box",
                  "max_device_bytes is not set"):
        assert words in e.value.message, e.value.message


# ---- torch: the differentiable distance (issue 30.2) ----

def smooth_cells(field, points):
    """The points whose distance is uncapped and at least 4 cells, and whose nearest obstacle stays
    the same one cell away along each axis: where the distance is a smooth function."""
    distance, obstacle, _, squared = field.distances(points)
    keep = (squared >= 16) & (squared != octovk.DistanceField.NO_OBSTACLE_CELLS) & (
        distance < field.max_distance_m - 2 * RES)
    for a in range(3):
        for sign in (-1, 1):
            moved = points.copy()
            moved[:, a] += sign * RES
            _, near, _, _ = field.distances(moved)
            keep &= (near == obstacle).all(axis=1)
    return points[keep]


def test_torch_distances_are_the_field_and_differentiable(context):
    import torch  # Debian's python3-torch, as test_arrays.py
    m = make_map()
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance_m=1.0,
                                 treat_unknown_as_occupied=False)
    rng = np.random.default_rng(4)
    brute = Brute(m, False)
    points = np.ascontiguousarray(centre_of(brute.min_key + brute.cells))  # every cell's centre
    distance, _, gradient, _ = field.distances(points)

    # Forward: the field's distance, in the input's dtype; backward: grad_out times the gradient.
    p = torch.tensor(points, dtype=torch.float64, requires_grad=True)
    d = field.torch_distances(p)
    assert d.dtype == torch.float64 and d.shape == (len(points),)
    np.testing.assert_array_equal(d.detach().numpy(), distance.astype(np.float64))
    weights = torch.tensor(rng.normal(size=len(points)))
    (grad,) = torch.autograd.grad(d, p, grad_outputs=weights)
    np.testing.assert_allclose(grad.numpy(), weights.numpy()[:, None] * gradient, rtol=1e-6)
    # The same class through autograd_function(), with points of shape (..., 3).
    fn = octovk.DistanceField.autograd_function()
    assert issubclass(fn, torch.autograd.Function)
    p2 = torch.tensor(points[:12].reshape(3, 4, 3), requires_grad=True)
    d2 = fn.apply(p2, field)
    assert d2.shape == (3, 4) and d2.dtype == torch.float32
    d2.sum().backward()
    np.testing.assert_array_equal(p2.grad.reshape(12, 3).numpy(), gradient[:12])

    # Finite differences over one cell where the field is smooth (gradcheck's idea; the field
    # is constant within a cell, so the step is a whole cell): the central difference of the
    # distance follows the gradient.
    smooth = smooth_cells(field, points)
    assert len(smooth) > 50, "too few smooth cells to check"
    _, _, g, _ = field.distances(smooth)
    for a in range(3):
        step = np.zeros(3, np.float32)
        step[a] = RES
        ahead = field.torch_distances(torch.from_numpy(smooth + step))
        behind = field.torch_distances(torch.from_numpy(smooth - step))
        central = ((ahead - behind) / (2 * RES)).numpy()
        np.testing.assert_allclose(central, g[:, a], atol=0.05)

    # Through a chain: moving the points along the gradient raises their distance.
    shift = torch.zeros(3, requires_grad=True)
    loss = field.torch_distances(torch.from_numpy(smooth) + shift).sum()
    loss.backward()
    np.testing.assert_allclose(shift.grad.numpy(), g.sum(axis=0, dtype=np.float64), atol=1e-4)
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        field.torch_distances(torch.zeros(4, 2))
