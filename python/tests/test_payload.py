"""ColorMap and StampedMap (issue 29), OctoMap's ColorOcTree and OcTreeStamped: their arguments
(refused with the fix named, the map left as it was), colours and stamps worked out by hand on
tiny scans, and whole scans against OctoMap's own trees (octovk_py_oracle colorscan/stampscan,
python/tests/octomap_oracle.cpp), bit for bit. The values need the device side of the payloads."""

import math

import numpy as np
import pytest
import torch

import octovk
from conftest import room_scans, run, tool, unproject

WHITE = [255, 255, 255]
PAYLOAD_RECORD = np.dtype([("state", "u1"), ("log_odds", "<f4"), ("depth", "u1"),
                           ("payload", "<u4")])

# At 0.1 m: two points in one cell 1 m ahead on x, one in a cell 1 m ahead on y.
SAME_CELL = np.array([[1.01, 0.01, 0.01], [1.04, 0.02, 0.03]], np.float32)
OTHER_CELL = np.array([[0.01, 1.01, 0.01]], np.float32)
FREE_CELL = np.array([[0.55, 0.01, 0.01]], np.float32)  # on the rays to SAME_CELL
UNKNOWN = np.array([[5.0, 5.0, 5.0]], np.float32)


def three_points():
    return np.concatenate([SAME_CELL, OTHER_CELL])


# ---- arguments: refused before anything reaches the map ----

def test_color_map_is_a_map_with_the_same_keywords(context):
    m = octovk.ColorMap(0.05, prob_hit=0.8, clamping_max=0.9, max_device_bytes=64 << 20)
    assert isinstance(m, octovk.Map)
    assert (m.resolution, m.prob_hit, m.clamping_max) == (0.05, 0.8, 0.9)
    assert m.context is context
    assert repr(m) == "ColorMap(resolution=0.050000)"
    s = octovk.StampedMap(resolution=0.2)
    assert isinstance(s, octovk.Map) and repr(s) == "StampedMap(resolution=0.200000)"
    # Every Map call works on them: a scan without colour or stamp, search, counts.
    m.insert_point_cloud(three_points(), (0, 0, 0))
    s.insert_point_cloud(three_points(), (0, 0, 0), stamp=7)
    for a in (m, s):
        state, _, _ = a.search(three_points())
        assert (state == octovk.CellState.OCCUPIED).all()
        assert a.node_count() > 0 and a.leaf_count() > 0


def test_colors_of_a_wrong_dtype_or_shape_are_refused_naming_what_is_expected(context):
    m = octovk.ColorMap(0.1)
    p = three_points()
    with pytest.raises(TypeError, match=r"colors: expected a C-contiguous uint8 array of shape "
                                        r"\(3, 3\), got a float32 array.*r, g, b"):
        m.insert_point_cloud(p, (0, 0, 0), colors=np.zeros((3, 3), np.float32))
    with pytest.raises(ValueError, match=r"colors: expected .*uint8 array of shape \(3, 3\), "
                                         r"got shape \(2, 3\).*one uint8 r, g, b"):
        m.insert_point_cloud(p, (0, 0, 0), colors=np.zeros((2, 3), np.uint8))
    with pytest.raises(ValueError, match=r"shape \(3, 3\), got shape \(3, 4\)"):
        m.submit_point_cloud(p, (0, 0, 0), colors=np.zeros((3, 4), np.uint8))
    with pytest.raises(ValueError, match=r"shape \(3, 3\), got shape \(9,\)"):
        m.insert_point_cloud(p, (0, 0, 0), colors=np.zeros(9, np.uint8))
    # An organised cloud takes colours of its shape.
    with pytest.raises(ValueError, match=r"shape \(1, 3, 3\), got shape \(3, 3\)"):
        m.insert_point_cloud(p.reshape(1, 3, 3), (0, 0, 0), colors=np.zeros((3, 3), np.uint8))
    with pytest.raises(ValueError, match="color_fold: expected 'average'.*'integrate'.*'mean'"):
        m.insert_point_cloud(p, (0, 0, 0), colors=np.zeros((3, 3), np.uint8), color_fold="mean")
    depth = np.ones((2, 4), np.float32)
    with pytest.raises(ValueError, match=r"colors: .*shape \(2, 4, 3\), got shape \(4, 2, 3\)"):
        m.insert_depth_image(depth, 2, 2, 2, 1, 1.0, colors=np.zeros((4, 2, 3), np.uint8))
    with pytest.raises(TypeError, match=r"colors: .*uint8.*got a uint16"):
        m.submit_depth_image(depth, 2, 2, 2, 1, 1.0, colors=np.zeros((2, 4, 3), np.uint16))
    assert m.node_count() == 0 and m.scans_in_flight == 0  # nothing was inserted
    # A plain Map has no colours to take.
    with pytest.raises(TypeError):
        octovk.Map(0.1).insert_point_cloud(p, (0, 0, 0), colors=np.zeros((3, 3), np.uint8))
    # Strided colours are copied (the library copies them anyway), None means no colour.
    m.insert_point_cloud(p, (0, 0, 0), colors=np.zeros((3, 4), np.uint8)[:, :3])
    m.insert_point_cloud(p, (0, 0, 0), colors=None)
    assert m.node_count() > 0


@pytest.mark.parametrize("bad", [-1, 2**32, 1.5, True, "100", np.float32(3)])
def test_stamps_outside_whole_seconds_are_value_errors(context, bad):
    m = octovk.StampedMap(0.1)
    p = three_points()
    with pytest.raises(ValueError, match=r"stamp: expected whole seconds, an int from 0 to "
                                         r"2\*\*32 - 1"):
        m.insert_point_cloud(p, (0, 0, 0), stamp=bad)
    with pytest.raises(ValueError, match="stamp: expected whole seconds"):
        m.submit_point_cloud(p, (0, 0, 0), stamp=bad)
    with pytest.raises(ValueError, match="stamp: expected whole seconds"):
        m.insert_depth_image(np.ones((2, 2), np.float32), 1, 1, 1, 1, 1.0, stamp=bad)
    with pytest.raises(ValueError, match="threshold_s: expected whole seconds"):
        m.degrade_outdated(bad, now=10)
    with pytest.raises(ValueError, match="now: expected whole seconds"):
        m.degrade_outdated(10, now=bad)
    assert m.node_count() == 0 and m.scans_in_flight == 0


def test_stamps_at_the_ends_of_their_range_and_numpy_integers_are_taken(context):
    m = octovk.StampedMap(0.1)
    for stamp in (0, 2**32 - 1, np.uint32(5), np.int64(6), None):
        m.insert_point_cloud(three_points(), (0, 0, 0), stamp=stamp)
    assert m.node_count() > 0


def test_reading_a_file_gives_the_class_of_its_tree_type(context, tmp_path):
    m = octovk.Map(0.1)
    m.insert_point_cloud(three_points(), (0, 0, 0))
    m.write(tmp_path / "plain.ot")
    assert type(octovk.Map.read(tmp_path / "plain.ot")) is octovk.Map
    for cls, wanted in ((octovk.ColorMap, "ColorOcTree"), (octovk.StampedMap, "OcTreeStamped")):
        with pytest.raises(octovk.FormatError, match=f"its tree type is OcTree, not {wanted}; "
                                                     r"octovk.Map.read\(path\) reads every"):
            cls.read(tmp_path / "plain.ot")


# ---- values: colours and stamps by hand ----

def test_colors_average_in_the_clouds_order_and_set_new_cells(context):
    m = octovk.ColorMap(0.1)
    p = np.concatenate([SAME_CELL, SAME_CELL[:1], OTHER_CELL])
    colors = np.array([[10, 20, 30], [20, 40, 60], [40, 80, 120], [1, 2, 3]], np.uint8)
    m.insert_point_cloud(p, (0, 0, 0), colors=colors)
    # (10, 20, 30) then (20, 40, 60): (15, 30, 45); then (40, 80, 120): (27, 55, 82), integer
    # means per channel (ColorOcTree::averageNodeColor); the other cell, unset, takes its colour.
    got = m.colors(np.concatenate([SAME_CELL, OTHER_CELL, FREE_CELL, UNKNOWN]))
    assert got.dtype == np.uint8 and got.shape == (5, 3)
    np.testing.assert_array_equal(got, [[27, 55, 82], [27, 55, 82], [1, 2, 3], WHITE, WHITE])
    # The colour of the cell a ray hits: colors() of its end, the hit cell's centre.
    hit, end = m.cast_rays((0, 0, 0), np.array([[1, 0, 0], [0, 1, 0]], np.float32))
    assert hit.tolist() == [1, 1]
    np.testing.assert_array_equal(m.colors(end), [[27, 55, 82], [1, 2, 3]])
    # A second scan averages with what the cells hold; a scan without colours leaves them.
    m.insert_point_cloud(OTHER_CELL, (0, 0, 0), colors=np.array([[3, 4, 5]], np.uint8))
    m.insert_point_cloud(OTHER_CELL, (0, 0, 0))
    np.testing.assert_array_equal(m.colors(OTHER_CELL), [[2, 3, 4]])
    # The reverse order gives another colour: the fold follows the cloud.
    r = octovk.ColorMap(0.1)
    r.insert_point_cloud(p[2::-1].copy(), (0, 0, 0), colors=colors[2::-1].copy())
    np.testing.assert_array_equal(r.colors(SAME_CELL[:1]), [[20, 40, 60]])


def test_colors_integrate_weighted_by_the_cells_occupancy(context):
    m = octovk.ColorMap(0.1)
    colors = np.array([[10, 20, 30], [20, 40, 60]], np.uint8)
    m.insert_point_cloud(SAME_CELL, (0, 0, 0), colors=colors, color_fold="integrate")
    # integrateNodeColor: unset takes (10, 20, 30); then old * p + new * (0.99 - p) truncated,
    # with p = 0.7 the occupancy after one hit: (12.8, 25.6, 38.4).
    np.testing.assert_array_equal(m.colors(SAME_CELL), [[12, 25, 38]] * 2)


def integrated_by_hand(old, new, log_odds):
    """ColorOcTree::integrateNodeColor's step in pure Python: p = octomap::probability of the
    node's float log-odds (math.exp is the C library's exp, as OctoMap's), the channels in double
    truncated toward zero and wrapped to 8 bits as liboctomap's conversion to uint8_t does on
    x86-64 (a negative channel needs p > 0.99)."""
    if tuple(old) == (255, 255, 255):
        return list(new)
    p = 1.0 - (1.0 / (1.0 + math.exp(float(log_odds))))
    return [int(float(o) * p + float(c) * (0.99 - p)) & 0xFF for o, c in zip(old, new)]


@pytest.mark.parametrize("clamping_max", [0.971, 0.999])
def test_colors_integrate_as_a_python_replica_of_octomaps_formula(context, clamping_max):
    # No OctoMap Python binding here: the cells' colours scan after scan against the formula
    # (test_color_scans_equal_octomaps_color_octree holds whole scans to OctoMap's C++ tree).
    # At clamping_max 0.999 the occupancy passes 0.99 and dark after bright goes negative.
    m = octovk.ColorMap(0.1, clamping_max=clamping_max)
    points = np.concatenate([SAME_CELL, SAME_CELL[:1], OTHER_CELL])
    cells = {0: WHITE, 3: WHITE}  # SAME_CELL's colour (points 0 to 2), OTHER_CELL's (point 3)
    wrapped = 0
    for scan in range(14):
        rng = np.random.default_rng(scan)
        colors = rng.integers(0, 256, (4, 3)).astype(np.uint8)
        if scan < 8:
            colors[:, :] = [1, 2, 0]  # dark while the occupancy climbs past 0.99
        elif scan % 2:
            colors[:, :] = [250, 240, 230]
        m.insert_point_cloud(points, (0, 0, 0), colors=colors, color_fold="integrate")
        _, log_odds, _ = m.search(points)
        for i, cell in ((0, 0), (1, 0), (2, 0), (3, 3)):
            before = cells[cell]
            cells[cell] = integrated_by_hand(before, colors[i].tolist(), log_odds[i])
            p = 1.0 - (1.0 / (1.0 + math.exp(float(log_odds[i]))))
            wrapped += tuple(before) != (255, 255, 255) and any(
                float(o) * p + float(c) * (0.99 - p) < 0 for o, c in zip(before, colors[i]))
        np.testing.assert_array_equal(m.colors(points),
                                      [cells[0], cells[0], cells[0], cells[3]], f"scan {scan}")
    assert (wrapped > 0) == (clamping_max > 0.99)


def test_colors_come_as_the_points_come(context):
    m = octovk.ColorMap(0.1)
    m.insert_point_cloud(three_points().reshape(1, 3, 3), (0, 0, 0),
                         colors=np.array([[[10, 20, 30], [20, 40, 60], [1, 2, 3]]], np.uint8))
    got = m.colors(three_points().reshape(3, 1, 3))
    assert got.shape == (3, 1, 3)
    np.testing.assert_array_equal(got[:, 0], [[15, 30, 45], [15, 30, 45], [1, 2, 3]])
    # (N, 4) points with copy=True, and a submitted scan with strided colours: the same map.
    s = octovk.ColorMap(0.1)
    p4 = np.concatenate([three_points(), np.zeros((3, 1), np.float32)], axis=1)
    rgba = np.array([[10, 20, 30, 0], [20, 40, 60, 0], [1, 2, 3, 0]], np.uint8)
    s.submit_point_cloud(p4, (0, 0, 0), colors=rgba[:, :3], copy=True)
    s.flush()
    np.testing.assert_array_equal(s.colors(p4, copy=True), m.colors(three_points()))


def test_torch_tensors_in_give_tensors_out(context):
    p = torch.from_numpy(three_points())
    c = octovk.ColorMap(0.1)
    c.insert_point_cloud(p, (0, 0, 0), colors=torch.tensor([[10, 20, 30], [20, 40, 60],
                                                            [1, 2, 3]], dtype=torch.uint8))
    got = c.colors(p)
    assert isinstance(got, torch.Tensor) and got.dtype == torch.uint8 and got.shape == (3, 3)
    assert got.tolist() == [[15, 30, 45], [15, 30, 45], [1, 2, 3]]
    s = octovk.StampedMap(0.1)
    s.insert_point_cloud(p, (0, 0, 0), stamp=2**32 - 1)
    stamps = s.stamps(p)  # torch has no uint32: int64, which holds every stamp
    assert isinstance(stamps, torch.Tensor) and stamps.dtype == torch.int64
    assert stamps.tolist() == [2**32 - 1] * 3


@pytest.mark.parametrize("submit", [False, True], ids=["insert", "submit"])
def test_depth_image_colors_equal_those_of_its_points(context, submit):
    rng = np.random.default_rng(4)
    h, w = 12, 16
    depth = rng.uniform(0.5, 2.0, (h, w)).astype(np.float32)
    depth[0, :3] = 0  # skipped pixels fold no colour
    rgb = rng.integers(0, 255, (h, w, 3)).astype(np.uint8)
    fx, fy, cx, cy = 12.0, 12.0, 7.5, 5.5
    pose = ((0.2, 0.1, 0.5), (0.0, 0.0, 0.0, 1.0))
    a = octovk.ColorMap(0.05)
    if submit:
        a.submit_depth_image(depth, fx, fy, cx, cy, 1.0, pose, colors=rgb)
        a.flush()
    else:
        a.insert_depth_image(depth, fx, fy, cx, cy, 1.0, pose, colors=rgb)
    points, keep = unproject(depth, fx, fy, cx, cy, 1.0, with_mask=True)
    b = octovk.ColorMap(0.05)
    b.insert_point_cloud(points, (0, 0, 0), pose=pose, colors=np.ascontiguousarray(rgb[keep]))
    centers = np.ascontiguousarray(b.leaves_in_box((-5, -5, -5), (5, 5, 5), True)[0])
    assert len(centers) > 20
    got = a.colors(centers)
    np.testing.assert_array_equal(got, b.colors(centers))
    # The cells took the image's random colours (each a pixel's, or a mean of several).
    assert len(np.unique(got, axis=0)) > len(centers) // 2
    assert not (got == 255).all(axis=1).any()


def test_stamps_of_updated_cells_are_the_scans(context):
    m = octovk.StampedMap(0.1)
    assert m.last_update_time() == 0
    m.insert_point_cloud(SAME_CELL, (0, 0, 0), stamp=1000)
    m.insert_point_cloud(OTHER_CELL, (0, 0, 0), stamp=2000)
    got = m.stamps(np.concatenate([SAME_CELL, FREE_CELL, OTHER_CELL, UNKNOWN]))
    assert got.dtype == np.uint32 and got.shape == (5,)
    np.testing.assert_array_equal(got, [1000, 1000, 1000, 2000, 0])
    assert m.last_update_time() == 2000


def test_degrade_outdated_gives_old_occupied_cells_one_miss(context):
    m = octovk.StampedMap(0.1)
    m.insert_point_cloud(SAME_CELL, (0, 0, 0), stamp=1000)
    m.insert_point_cloud(OTHER_CELL, (0, 0, 0), stamp=2000)
    probe = np.concatenate([SAME_CELL[:1], OTHER_CELL, FREE_CELL])
    _, before, _ = m.search(probe)
    m.degrade_outdated(threshold_s=500, now=2100)
    state, after, _ = m.search(probe)
    # SAME_CELL: 1100 s > 500 s old and occupied, one miss (float arithmetic, as OctoMap's
    # updateNodeLogOdds), its stamp kept; OTHER_CELL: 100 s old; FREE_CELL: not occupied.
    miss = np.float32(np.log(0.4 / 0.6))
    assert after[0] == np.float32(before[0] + miss) and after[0] < before[0]
    assert after[1] == before[1] and after[2] == before[2]
    np.testing.assert_array_equal(m.stamps(probe), [1000, 2000, 1000])
    assert m.last_update_time() == 2100  # the inner nodes' stamps: now
    # Unsigned, as OctoMap: a stamp after now is (now - stamp) mod 2**32 old.
    m.degrade_outdated(threshold_s=2**32 - 200, now=1900)
    _, again, _ = m.search(probe)
    assert again[1] == np.float32(after[1] + miss) and again[0] == after[0]


# ---- values: whole scans against OctoMap's ColorOcTree and OcTreeStamped ----

def write_scans(path, scans):
    with open(path, "wb") as f:
        for points, origin, stamp, colors in scans:
            np.array([len(points)], "<u4").tofile(f)
            np.asarray(origin, "<f4").tofile(f)
            np.array([stamp], "<u4").tofile(f)
            np.ascontiguousarray(points, "<f4").tofile(f)
            np.ascontiguousarray(colors, np.uint8).tofile(f)


def oracle(tmp_path, command, args, scans, queries):
    write_scans(tmp_path / "scans", scans)
    queries.tofile(tmp_path / "queries.f32")
    out = str(tmp_path / "out")
    if command == "colorscan":
        run([tool("OCTOVK_PY_ORACLE"), command, *args[:2], str(tmp_path / "scans"),
             str(tmp_path / "queries.f32"), out])
    else:
        run([tool("OCTOVK_PY_ORACLE"), command, args[0], str(tmp_path / "scans"),
             str(tmp_path / "queries.f32"), *args[1:], out])
    want = np.fromfile(out, PAYLOAD_RECORD)
    assert len(want) == len(queries)
    return want


def assert_search_equal(m, queries, want):
    state, log_odds, depth = m.search(queries)
    np.testing.assert_array_equal(state, want["state"])
    np.testing.assert_array_equal(log_odds.view(np.uint32), want["log_odds"].view(np.uint32))
    np.testing.assert_array_equal(depth, want["depth"])
    return state


def payload_scans(seed):
    """Two small room scans (one with a repeated point), each with colours and a stamp."""
    rng = np.random.default_rng(seed)
    out = []
    for i, (points, origin) in enumerate(room_scans(seed=seed, scans=2, points=300)):
        points = np.concatenate([points, points[:5]])  # cells hit twice in one scan
        colors = rng.integers(0, 255, (len(points), 3)).astype(np.uint8)
        out.append((points, origin, 100 + 50 * i, colors))
    return out


def payload_queries(scans, seed=3):
    rng = np.random.default_rng(seed)
    q = rng.uniform(-2.5, 2.5, (600, 3)).astype(np.float32)
    q[:, 2] *= 0.4
    return np.ascontiguousarray(np.concatenate([q] + [s[0] for s in scans]), np.float32)


@pytest.mark.parametrize("fold", ["average", "integrate"])
def test_color_scans_equal_octomaps_color_octree(context, tmp_path, fold):
    scans = payload_scans(21)
    m = octovk.ColorMap(0.05)
    for points, origin, _, colors in scans:
        m.insert_point_cloud(points, origin, colors=colors, color_fold=fold)
    queries = payload_queries(scans)
    want = oracle(tmp_path, "colorscan", ["0.05", fold], scans, queries)
    assert_search_equal(m, queries, want)
    got = m.colors(queries).astype(np.uint32)
    packed = got[:, 0] | (got[:, 1] << 8) | (got[:, 2] << 16)
    found = want["state"] != 0
    np.testing.assert_array_equal(packed[found], want["payload"][found])
    assert (packed[~found] == 0xFFFFFF).all()  # white where search finds nothing
    assert (packed[found] != 0xFFFFFF).sum() > 100


def test_stamped_scans_and_degrade_equal_octomaps_octree_stamped(context, tmp_path):
    scans = payload_scans(22)
    m = octovk.StampedMap(0.05)
    for points, origin, stamp, _ in scans:
        m.insert_point_cloud(points, origin, stamp=stamp)
    queries = payload_queries(scans)
    want = oracle(tmp_path, "stampscan", ["0.05"], scans, queries)
    state = assert_search_equal(m, queries, want)
    np.testing.assert_array_equal(m.stamps(queries), want["payload"])
    assert set(np.unique(want["payload"][state != 0])) == {100, 150}
    # degradeOutdatedNodes at 200 with 60 s: the first scan's occupied leaves take a miss.
    m.degrade_outdated(60, now=200)
    want = oracle(tmp_path, "stampscan", ["0.05", "200", "60"], scans, queries)
    assert_search_equal(m, queries, want)
    np.testing.assert_array_equal(m.stamps(queries), want["payload"])


def test_payload_maps_written_and_read_back_keep_their_class_and_colors(context, tmp_path):
    c = octovk.ColorMap(0.1)
    c.insert_point_cloud(three_points(), (0, 0, 0),
                         colors=np.array([[10, 20, 30], [20, 40, 60], [1, 2, 3]], np.uint8))
    c.write(tmp_path / "color.ot")
    for read in (octovk.Map.read, octovk.ColorMap.read):
        back = read(tmp_path / "color.ot")
        assert type(back) is octovk.ColorMap
        np.testing.assert_array_equal(back.colors(three_points()), c.colors(three_points()))
        assert back.node_count() == c.node_count()
    s = octovk.StampedMap(0.1)
    s.insert_point_cloud(three_points(), (0, 0, 0), stamp=1000)
    s.write(tmp_path / "stamped.ot")
    back = octovk.Map.read(tmp_path / "stamped.ot")
    assert type(back) is octovk.StampedMap and back.node_count() == s.node_count()
    # OctoMap's .ot holds no stamps: they come back from the stamped.ot.stamps beside it.
    np.testing.assert_array_equal(back.stamps(three_points()), [1000] * 3)
    with pytest.raises(octovk.FormatError, match="its tree type is ColorOcTree, not OcTreeStamped"):
        octovk.StampedMap.read(tmp_path / "color.ot")
