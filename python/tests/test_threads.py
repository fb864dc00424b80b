"""The module in a Python process: the GIL is released during device work, maps on threads
sharing one Context equal maps built alone, calls on one map from two threads are serialised,
and Ctrl-C (SIGINT) interrupts a long flush() without harming the map."""

import os
import signal
import threading
import time

import numpy as np

import octovk
from conftest import room_scans


def sphere_scan(n, radius, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3)).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.ascontiguousarray(d * np.float32(radius))


def test_main_thread_runs_python_during_an_insert(context):
    m = octovk.Map(0.05)
    scan = sphere_scan(3000, 2.0, 1)
    inside = {}

    def work():
        inside["start"] = time.perf_counter()
        m.insert_point_cloud(scan, (0, 0, 0))
        inside["end"] = time.perf_counter()

    worker = threading.Thread(target=work)
    ticks = []
    worker.start()
    while worker.is_alive():
        ticks.append(time.perf_counter())  # Python bytecode, while the worker is in the library
    worker.join()
    start, end = inside["start"], inside["end"]
    assert end - start > 0.02, "the insert was too short to tell"
    # With the GIL held through the call, no tick could fall inside it (the main thread would
    # wait for the call to return); released, the main thread keeps running throughout.
    during = [t for t in ticks if start + 0.005 < t < end - 0.005]
    assert len(during) > 100, f"{len(during)} main-thread iterations during a {end - start:.3f} s insert"


def test_maps_on_threads_sharing_a_context_equal_maps_built_alone(context, tmp_path):
    scans = room_scans(seed=21, scans=3, points=600)

    def build(name):
        m = octovk.Map(0.05, context=context)
        for points, origin in scans:
            m.submit_point_cloud(points, origin)
        m.flush()
        m.write(tmp_path / f"{name}.ot")

    build("alone")
    threads = [threading.Thread(target=build, args=(f"t{i}",)) for i in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    want = (tmp_path / "alone.ot").read_bytes()
    for i in range(3):
        assert (tmp_path / f"t{i}.ot").read_bytes() == want


def test_one_map_used_from_two_threads_is_serialised(context):
    m = octovk.Map(0.05)
    scans = room_scans(seed=5, scans=6, points=300)
    errors = []

    def work(part):
        try:
            for points, origin in scans[part::2]:
                m.insert_point_cloud(points, origin)
                m.search(points)
        except Exception as e:  # reported below, with the thread's error
            errors.append(e)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert m.scans_in_flight == 0
    state, _, _ = m.search(np.concatenate([p for p, _ in scans]))
    assert (state == int(octovk.CellState.OCCUPIED)).sum() > 0


def test_ctrl_c_interrupts_a_long_flush_and_the_map_stays_whole(context, tmp_path):
    m = octovk.Map(0.05)
    scans = [sphere_scan(8000, 1.5 + 0.3 * i, 10 + i) for i in range(3)]
    # Blocking inserts first, so that the flush below runs no growth (whose re-runs one poll
    # would wait for).
    for s in scans:
        m.insert_point_cloud(s, (0, 0, 0))
    m.write(tmp_path / "before.ot")
    # SIGINT from another thread once flush() runs: that thread needs the GIL, which the main
    # thread releases only inside flush() (its polls then see the signal).
    go = threading.Event()

    def interrupt():
        go.wait()
        os.kill(os.getpid(), signal.SIGINT)

    killer = threading.Thread(target=interrupt)
    killer.start()
    tickets = [m.submit_point_cloud(s, (0, 0, 0)) for s in scans]
    interrupted = False
    try:
        go.set()
        m.flush()
    except KeyboardInterrupt:
        interrupted = True
    killer.join()
    # Raised by flush() itself, before its scans were in the map (a signal after its return
    # would be raised at the same line, with every scan in).
    assert interrupted
    assert m.scans_in_flight > 0
    # The scans are still submitted; the next flush completes them, in order, and the map is
    # the map of the same scans inserted one by one.
    m.flush()
    assert m.scans_in_flight == 0
    assert [s.ticket for s in m.take_scan_stats()] == tickets
    m.write(tmp_path / "interrupted.ot")
    ref = octovk.Map.read(tmp_path / "before.ot")
    for s in scans:
        ref.insert_point_cloud(s, (0, 0, 0))
    ref.write(tmp_path / "ref.ot")
    assert (tmp_path / "interrupted.ot").read_bytes() == (tmp_path / "ref.ot").read_bytes()
