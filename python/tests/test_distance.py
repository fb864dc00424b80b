"""octovk.DistanceField against brute force in numpy: the exact squared distances of every cell of
the box (the minimum over every occupied cell, found with Map.search on each cell's centre), and
batched queries (distance, nearest obstacle, gradient, clearance of spheres) cell for cell. The C++
tests (tests/distance_test.cpp) compare the same field with brute force and dynamicEDT3D."""

import gc
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
    """OctoMap's coordToKey of float coordinates (the library takes floats), in double."""
    c = np.asarray(coords, np.float32).astype(np.float64)
    return np.floor(c * (1.0 / RES)).astype(np.int64) + 32768


def centre_of(keys):
    return ((np.asarray(keys, np.float64) - 32768 + 0.5) * RES).astype(np.float32)


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
        c = key_of(points) - self.min_key
        inside = np.all((c >= 0) & (c < self.size), axis=1)
        flat = c[:, 0] + self.size[0] * (c[:, 1] + self.size[1] * c[:, 2])
        return np.where(inside, flat, -1)


@pytest.mark.parametrize("unknown_occupied", [False, True])
def test_every_cell_equals_brute_force(context, unknown_occupied):
    m = make_map()
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance=0.7,
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
    assert field.max_distance == pytest.approx(0.7)


def test_queries_equal_brute_force(context):
    m = make_map()
    max_d = 0.5
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance=max_d)
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
    field = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance=0.8)
    before, _ = field.download()
    for points, origin in room_scans(seed=9, scans=2, points=400):
        m.submit_point_cloud(points, origin)
    field.update()  # sees the submitted scans
    after, _ = field.download()
    scratch, _ = octovk.DistanceField(m, BOX_MIN, BOX_MAX, max_distance=0.8).download()
    np.testing.assert_array_equal(after, scratch)
    assert not np.array_equal(before, after)
    np.testing.assert_array_equal(after.ravel(), Brute(m, False).squared)
    assert field.last_update_ms >= 0.0


def test_bad_input_and_memory(context):
    m = octovk.Map(RES)
    base = m.device_bytes().total
    with pytest.raises(octovk.InvalidArgumentError, match="inverted"):
        octovk.DistanceField(m, (1, 0, 0), (0, 1, 1))
    with pytest.raises(octovk.InvalidArgumentError, match="NaN"):
        octovk.DistanceField(m, (0, 0, 0), (1, 1, float("nan")))
    with pytest.raises(octovk.InvalidArgumentError, match="max_distance_m"):
        octovk.DistanceField(m, (0, 0, 0), (1, 1, 1), max_distance=0.0)
    with pytest.raises(ValueError, match="min"):
        octovk.DistanceField(m, (0, 0), (1, 1, 1))
    assert m.device_bytes().total == base
    field = octovk.DistanceField(m, (0, 0, 0), (1, 1, 1))
    assert m.device_bytes().distance_fields == field.device_bytes() > 0
    with pytest.raises(TypeError, match="points"):
        field.distances(np.zeros((3, 3), np.float64))
    with pytest.raises(ValueError, match="spheres"):
        field.clearances(np.zeros((3, 3), np.float32))
    distance, obstacle, _, squared = field.distances(np.zeros((0, 3), np.float32))
    assert distance.shape == (0,) and obstacle.shape == (0, 3)
    # An empty map: no obstacle anywhere in the box.
    _, _, _, squared = field.distances(np.full((1, 3), 0.5, np.float32))
    assert squared[0] == octovk.DistanceField.NO_OBSTACLE_CELLS
    # Too large for the cap: refused, naming the bytes.
    capped = octovk.Map(RES, max_device_bytes=base + (1 << 20))
    with pytest.raises(octovk.OutOfDeviceMemoryError, match="bytes"):
        octovk.DistanceField(capped, (0, 0, 0), (6, 6, 6))
    del field
    gc.collect()
    assert m.device_bytes().total == base


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
