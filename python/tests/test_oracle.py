"""The module's maps and answers against OctoMap: .bt/.ot bytes against graph2tree on the same
scan graphs, and search / castRay / leaf_bbx_iterator against OctoMap's own answers on the same
map (octovk_py_oracle, python/tests/octomap_oracle.cpp), bit for bit."""

import os
import sys

import numpy as np
import pytest

import octovk
from conftest import octomap_data, require, room_scans, run, tool, unproject

SEARCH_RECORD = np.dtype([("state", "u1"), ("log_odds", "<f4"), ("depth", "u1")])
RAY_RECORD = np.dtype([("hit", "u1"), ("end", "<f4", (3,))])


def integrate_graph(graph, resolution, submit, **scan):
    """A map of every scan of `graph`, placed as graph2tree places them."""
    m = octovk.Map(resolution)
    for points, pose in octovk.read_scan_graph(graph):
        origin = octovk.graph2tree_sensor_origin(pose)
        if submit:
            m.submit_point_cloud(points, origin, pose, **scan)
        else:
            m.insert_point_cloud(points, origin, pose=pose, **scan)
    m.flush()
    return m


def graph2tree(graph, out, resolution, max_range=None):
    args = [tool("OCTOVK_GRAPH2TREE"), "-i", graph, "-o", out, "-res", str(resolution)]
    if max_range is not None:
        args += ["-m", str(max_range)]
    run(args, cwd=os.path.dirname(out))


def read_bytes(path):
    with open(path, "rb") as f:
        return f.read()


@pytest.fixture(scope="module")
def fr079_graph(tmp_path_factory):
    """The first 60 scans of the FR-079 log as a scan graph (as tests/cli_test.cpp cuts it)."""
    d = tmp_path_factory.mktemp("fr079")
    fr079 = os.path.join(os.environ.get("OCTOVK_SOURCE_DIR", ""), "tests", "data", "fr079-2d")
    log, graph = str(d / "fr079.log"), str(d / "fr079.graph")
    run([sys.executable, os.path.join(fr079, "clf2log.py"), os.path.join(fr079, "fr079.clf.bz2"),
         log, "60"])
    run([tool("OCTOVK_LOG2GRAPH"), log, graph])
    return graph


@pytest.mark.parametrize("submit", [False, True], ids=["insert", "submit"])
def test_spherical_scan_bt_and_ot_equal_graph2tree(context, tmp_path, submit):
    graph = octomap_data("spherical_scan.graph")
    ref = str(tmp_path / "graph2tree.bt")
    graph2tree(graph, ref, 0.1)
    m = integrate_graph(graph, 0.1, submit)
    m.write(tmp_path / "octovk.bt")
    m.write(str(tmp_path / "octovk.ot"))
    assert read_bytes(tmp_path / "octovk.bt") == read_bytes(ref)
    assert read_bytes(tmp_path / "octovk.ot") == read_bytes(ref + ".ot")


@pytest.mark.parametrize("max_range", [None, 5.0], ids=["unlimited", "max_range_5"])
def test_fr079_graph_bt_equals_graph2tree(context, tmp_path, fr079_graph, max_range):
    ref = str(tmp_path / "graph2tree.bt")
    graph2tree(fr079_graph, ref, 0.05, max_range)
    m = integrate_graph(fr079_graph, 0.05, True,
                        **({} if max_range is None else {"max_range_m": max_range}))
    assert m.take_scan_stats()[-1].ticket == 60
    m.write(tmp_path / "octovk.bt")
    assert read_bytes(tmp_path / "octovk.bt") == read_bytes(ref)
    # Read back: the same map, and the same bytes again.
    again = octovk.Map.read(tmp_path / "octovk.bt")
    assert again.resolution == 0.05
    assert again.node_count() == m.node_count()
    again.write(tmp_path / "again.bt")
    assert read_bytes(tmp_path / "again.bt") == read_bytes(ref)


@pytest.fixture(scope="module")
def room(context, tmp_path_factory):
    """A map of random room scans, and the same map as an .ot file for OctoMap."""
    m = octovk.Map(0.05, cast_ray_backend=octovk.CastRayBackend.WALK)
    for points, origin in room_scans():
        m.insert_point_cloud(points, origin)
    path = str(tmp_path_factory.mktemp("room") / "room.ot")
    m.write(path)
    return m, path


def query_points(n=3000, seed=3):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-2.5, 2.5, (n, 3)).astype(np.float32)
    p[:, 2] *= 0.4
    p[-3:] = [[1e7, 0, 0], [0, -1e7, 0], [0, 0, 0]]  # outside the map, and the origin
    return p


def test_search_equals_octomap(room, tmp_path):
    m, ot = room
    points = query_points()
    points.tofile(tmp_path / "points.f32")
    run([tool("OCTOVK_PY_ORACLE"), "search", ot, str(tmp_path / "points.f32"),
         str(tmp_path / "out")])
    want = np.fromfile(tmp_path / "out", SEARCH_RECORD)
    state, log_odds, depth = m.search(points)
    assert len(want) == len(points)
    np.testing.assert_array_equal(state, want["state"])
    np.testing.assert_array_equal(log_odds.view(np.uint32), want["log_odds"].view(np.uint32))
    np.testing.assert_array_equal(depth, want["depth"])
    assert (state == int(octovk.CellState.OCCUPIED)).sum() > 10
    assert (state == int(octovk.CellState.FREE)).sum() > len(points) // 10
    assert state[-3] == state[-2] == int(octovk.CellState.UNKNOWN)


def rays(n=2000, seed=5):
    rng = np.random.default_rng(seed)
    origins = (rng.uniform(-0.2, 0.2, (n, 3))).astype(np.float32)
    origins[n // 2:, 2] += 2.0  # half start in unknown space above the scans
    directions = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
    directions[:, 2] *= 0.3
    directions[0] = 0  # a zero direction: OctoMap's defined miss
    return origins, directions


def require_backend(context, backend):
    if backend == octovk.CastRayBackend.WALK:
        return
    query = backend == octovk.CastRayBackend.RAY_QUERY
    rt = context.device.ray_query_enabled if query else context.device.ray_tracing_pipeline
    way = "ray queries" if query else "ray-tracing pipelines"
    if os.environ.get("OCTOVK_EXPECT_RAY_QUERY", "") not in ("", "0"):
        assert rt, f"OCTOVK_EXPECT_RAY_QUERY is set but '{context.device.driver}' has no {way}"
    if not rt:
        pytest.skip(f"'{context.device.driver}' has no {way}: castRay's ray-tracing backend "
                    "is tested on Mesa 25's lavapipe")


@pytest.mark.parametrize("backend", [octovk.CastRayBackend.WALK, octovk.CastRayBackend.RAY_QUERY,
                                     octovk.CastRayBackend.RT_PIPELINE],
                         ids=["walk", "rt-query", "rt-pipeline"])
@pytest.mark.parametrize("max_range,ignore_unknown", [(-1.0, False), (-1.0, True), (1.2, False),
                                                      (0.7, True)])
def test_cast_rays_equal_octomap(context, room, tmp_path, max_range, ignore_unknown, backend):
    require_backend(context, backend)
    m, ot = room
    if backend != octovk.CastRayBackend.WALK:
        m = octovk.Map(0.05, cast_ray_backend=backend)
        for points, origin in room_scans():
            m.insert_point_cloud(points, origin)
    origins, directions = rays()
    records = np.zeros((len(origins), 8), np.float32)
    records[:, 0:3], records[:, 3:6] = origins, directions
    records[:, 6], records[:, 7] = max_range, float(ignore_unknown)
    records.tofile(tmp_path / "rays.f32")
    run([tool("OCTOVK_PY_ORACLE"), "castray", ot, str(tmp_path / "rays.f32"),
         str(tmp_path / "out")])
    want = np.fromfile(tmp_path / "out", RAY_RECORD)
    hit, end = m.cast_rays(origins, directions, max_range_m=max_range,
                           ignore_unknown=ignore_unknown)
    assert m.cast_ray_info().backend == backend
    np.testing.assert_array_equal(hit, want["hit"])
    np.testing.assert_array_equal(end.view(np.uint32), want["end"].view(np.uint32))
    assert 0 < hit.sum() < len(hit)


@pytest.mark.parametrize("occupied_only", [False, True])
def test_leaves_in_box_equal_octomap_iterator(room, tmp_path, occupied_only):
    m, ot = room
    lo, hi = (-1.0, -0.5, -0.25), (0.8, 1.0, 0.3)
    run([tool("OCTOVK_PY_ORACLE"), "leaves", ot, *map(str, lo + hi), str(int(occupied_only)),
         str(tmp_path / "out")])
    want = np.fromfile(tmp_path / "out", np.float32).reshape(-1, 5)
    centers, sizes, log_odds = m.leaves_in_box(lo, hi, occupied_only=occupied_only)
    got = np.concatenate([centers, sizes[:, None], log_odds[:, None]], axis=1)
    assert len(want) > 10
    key = lambda a: sorted(map(tuple, a.view(np.uint32).tolist()))  # noqa: E731
    assert key(got) == key(want)
    assert m.leaves_in_box((-1e7, 0, 0), (1, 1, 1))[0].shape == (0, 3)


@pytest.mark.parametrize("dtype", [np.uint16, np.float32])
def test_depth_image_equals_its_points(context, tmp_path, dtype):
    rng = np.random.default_rng(11)
    h, w = 48, 64
    if dtype == np.uint16:
        depth = rng.integers(2000, 12000, (h, w)).astype(np.uint16)
        scale = 5000.0
    else:
        depth = rng.uniform(0.4, 2.4, (h, w)).astype(np.float32)
        depth[3, :10] = np.nan
        scale = 1.0
    depth[0, :5] = 0
    fx, fy, cx, cy = 52.5, 52.5, 31.5, 23.5
    pose = ((0.5, -0.2, 1.0), (0.0, 0.0, 0.38268343, 0.92387953))
    a = octovk.Map(0.05)
    stats = a.insert_depth_image(depth, fx, fy, cx, cy, scale, pose)
    assert octovk._last_input_address() == depth.ctypes.data
    assert stats.points == h * w
    assert stats.skipped_no_depth == (5 if dtype == np.uint16 else 15)
    b = octovk.Map(0.05)
    b.insert_point_cloud(unproject(depth, fx, fy, cx, cy, scale), (0, 0, 0), pose=pose)
    c = octovk.Map(0.05)
    c.submit_depth_image(depth, fx, fy, cx, cy, scale, pose=octovk.Pose(*pose))
    c.flush()
    for m, name in ((a, "a"), (b, "b"), (c, "c")):
        m.write(tmp_path / f"{name}.ot")
    assert read_bytes(tmp_path / "a.ot") == read_bytes(tmp_path / "b.ot")
    assert read_bytes(tmp_path / "c.ot") == read_bytes(tmp_path / "b.ot")


def test_map_open_reads_a_store_as_graph2tree_builds_it(context, tmp_path):
    """Map.open: the map a store holds after `octovk integrate --store`, as its last committed
    scan left it: byte-identical to graph2tree's map of the same scans, and a snapshot."""
    graph = octomap_data("spherical_scan.graph")
    store = tmp_path / "map.sqlite"
    run([tool("OCTOVK_CLI"), "integrate", graph, "--store", str(store), "--map", "lab",
         "-r", "0.1", "-q"], cwd=tmp_path)
    m = octovk.Map.open(store, map="lab", context=context)
    assert type(m) is octovk.Map
    assert m.resolution == 0.1
    m.write(tmp_path / "opened.ot")
    graph2tree(graph, str(tmp_path / "g.bt"), 0.1)
    assert read_bytes(tmp_path / "opened.ot") == read_bytes(tmp_path / "g.bt.ot")
    with pytest.raises(octovk.InvalidArgumentError, match="holds no map 'default'"):
        octovk.Map.open(str(store), context=context)
    with pytest.raises(octovk.Error):
        octovk.Map.open(tmp_path / "missing.sqlite", context=context)


def test_store_follower_reads_only_what_was_committed_since(context, tmp_path):
    """StoreFollower: the first poll reads every tile, a poll with nothing committed returns
    None, a later one the tiles the new scans wrote; its map is the store's (store export)."""
    graph = octomap_data("spherical_scan.graph")
    store = str(tmp_path / "map.sqlite")
    cli = tool("OCTOVK_CLI")
    run([cli, "integrate", graph, "--store", store, "-r", "0.1", "-q"], cwd=tmp_path)
    follower = octovk.StoreFollower(store)
    first = follower.poll()
    assert first["seq"] >= 1 and follower.seq == first["seq"]
    assert first["changed"].dtype == np.float64 and first["changed"].shape[1] == 6
    assert len(first["changed"]) > 0 and len(first["dropped"]) == 0
    assert np.all(first["changed"][:, 3:] > first["changed"][:, :3])
    assert follower.poll() is None
    run([cli, "integrate", graph, "--store", store, "-q"], cwd=tmp_path)  # the same scans again
    second = follower.poll()
    assert second["seq"] == 2 * first["seq"]
    assert 0 < len(second["changed"]) <= len(first["changed"]) + len(second["dropped"])
    assert list(follower.updates(interval_s=0.01, until_seq=second["seq"])) == []
    follower.map(context=context).write(tmp_path / "followed.ot")
    run([cli, "store", "export", store, "-o", str(tmp_path / "export.ot")], cwd=tmp_path)
    assert read_bytes(tmp_path / "followed.ot") == read_bytes(tmp_path / "export.ot")
    with pytest.raises(octovk.InvalidArgumentError, match="holds no map 'lab'"):
        octovk.StoreFollower(store, map="lab")


def test_stored_map_commits_each_scan_as_graph2tree_builds_them(context, tmp_path):
    """StoredMap: every scan inserted is committed with its log row; the store's map (store
    export), the snapshot and graph2tree's map of the same scans are byte-identical."""
    graph = octomap_data("spherical_scan.graph")
    store = tmp_path / "written.sqlite"
    with pytest.raises(octovk.InvalidArgumentError, match="give MapParams to create it"):
        octovk.StoredMap.open(store, map="lab", context=context)
    stored = octovk.StoredMap.open(store, map="lab", resolution=0.1, context=context)
    scans = octovk.read_scan_graph(graph)
    for points, pose in scans:
        stored.insert_point_cloud(points, octovk.graph2tree_sensor_origin(pose), pose=pose,
                                  source="spherical")
    assert stored.last_seq == len(scans) and stored.name == "lab" and stored.resolution == 0.1
    cli = tool("OCTOVK_CLI")
    run([cli, "store", "export", str(store), "--map", "lab", "-o", str(tmp_path / "e.ot")],
        cwd=tmp_path)
    graph2tree(graph, str(tmp_path / "g.bt"), 0.1)
    expected = read_bytes(tmp_path / "g.bt.ot")
    assert read_bytes(tmp_path / "e.ot") == expected
    stored.snapshot().write(tmp_path / "s.ot")
    assert read_bytes(tmp_path / "s.ot") == expected
    log = run([cli, "store", "log", str(store), "--map", "lab"], cwd=tmp_path).splitlines()
    assert log[0] == "1 spherical 0" and len(log) == len(scans)


@pytest.mark.parametrize("tree_type", ["ColorOcTree", "OcTreeStamped"])
def test_stored_colour_and_stamped_maps_equal_the_same_scans_in_memory(context, tmp_path,
                                                                     tree_type):
    """A colour or stamped StoredMap (two writers taking turns): the committed map, read back
    as the class of its tree type, is the map those scans make in memory, file for file (a
    stamped map's stamps too); the in-memory maps are OctoMap's (test_payload.py)."""
    store = tmp_path / "payload.sqlite"
    one = octovk.StoredMap.open(store, resolution=0.1, tree_type=tree_type, context=context)
    two = octovk.StoredMap.open(store, context=context)  # exists: its own tree type
    assert one.tree_type == two.tree_type == tree_type
    memory = (octovk.ColorMap if tree_type == "ColorOcTree" else octovk.StampedMap)(
        0.1, context=context)
    rng = np.random.default_rng(5)
    for i, (points, origin) in enumerate(room_scans(seed=11, scans=4, points=400)):
        extra = {}
        if tree_type == "ColorOcTree":
            extra["colors"] = rng.integers(0, 256, (len(points), 3), dtype=np.uint8)
        else:
            extra["stamp"] = 1000 + 7 * i
        (one if i % 2 == 0 else two).insert_point_cloud(points, origin, **extra)
        memory.insert_point_cloud(points, origin, **extra)
    assert two.last_seq == 4
    read = octovk.Map.open(store, context=context)
    assert type(read) is type(memory) and type(two.snapshot()) is type(memory)
    read.write(tmp_path / "read.ot")
    memory.write(tmp_path / "memory.ot")
    assert read_bytes(tmp_path / "read.ot") == read_bytes(tmp_path / "memory.ot")
    follower = octovk.StoreFollower(store)
    follower.poll()
    assert follower.tree_type == tree_type and type(follower.map(context=context)) is type(memory)
    if tree_type == "OcTreeStamped":
        assert read_bytes(tmp_path / "read.ot.stamps") == read_bytes(tmp_path / "memory.ot.stamps")
    # Colours or a stamp for a map that holds none: refused by name, nothing committed.
    with pytest.raises(octovk.InvalidArgumentError, match="colours were given|holds no stamps"):
        if tree_type == "OcTreeStamped":
            one.insert_point_cloud(points, origin, colors=np.zeros((len(points), 3), np.uint8))
        else:
            one.insert_point_cloud(points, origin, stamp=5)
    assert octovk.StoreFollower(store).poll()["seq"] == 4
