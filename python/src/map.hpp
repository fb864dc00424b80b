// octovk.Map's C++ side: the OccupancyMap with its Context and the one lock that orders the
// threads using it (map.cpp binds it; distance.cpp's fields run under the same lock), and
// octovk.ColorMap / octovk.StampedMap, the same with a ColorMap or StampedMap inside.
#pragma once

#include <pybind11/pybind11.h>

#include <algorithm>
#include <chrono>
#include <mutex>
#include <optional>
#include <thread>
#include <variant>

#include "checked.hpp"
#include "octovk/octovk.hpp"
#include "octovk/store.hpp"

namespace octovk::python {

namespace py = pybind11;

class Map {
 public:
  /// The C++ map inside: which one decides the Python class (Map, ColorMap, StampedMap).
  using Held = std::variant<OccupancyMap, ColorMap, StampedMap>;

  Map(py::object context, Held map) : context_(std::move(context)), map_(std::move(map)) {}
  virtual ~Map() = default;

  /// Runs `work` on the map with the GIL released and the map's lock held (a map is used by one
  /// thread at a time; Python threads sharing one are ordered here). `work` touches no Python
  /// object.
  template <class Work>
  auto run(Work&& work) {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);
    return work(base());
  }

  /// run() on the map as the `Kind` it holds (ColorMap, StampedMap): only PyColorMap and
  /// PyStampedMap call it, which are made holding that kind.
  template <class Kind, class Work>
  auto runAs(Work&& work) {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);
    return work(std::get<Kind>(map_));
  }

  /// Waits until every submitted scan is in the map, polling so that a signal (Ctrl-C) is
  /// seen between polls: KeyboardInterrupt then leaves the scans in flight and the map
  /// consistent; the next flush() or query completes them.
  void flush() {
    auto pause = std::chrono::microseconds(20);
    for (;;) {
      const bool done = run([&](OccupancyMap& m) {
        if (m.scansInFlight() == 0) return true;
        return m.finished(last_ticket_);
      });
      if (done) break;
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      {
        py::gil_scoped_release release;
        std::this_thread::sleep_for(pause);
      }
      pause = std::min(pause * 2, std::chrono::microseconds(2000));
    }
    run([](OccupancyMap& m) { m.flush(); });  // nothing left: raises what finished() left
  }

  void noteTicket(ScanTicket ticket) { last_ticket_ = std::max(last_ticket_, ticket); }

  const py::object& context() const { return context_; }
  const OccupancyMap& map() const {
    return std::visit([](const auto& m) -> const OccupancyMap& { return m; }, map_);
  }

 private:
  OccupancyMap& base() {
    return std::visit([](auto& m) -> OccupancyMap& { return m; }, map_);
  }

  py::object context_;  // keeps the Context (and so the device) alive while the map lives
  std::mutex mutex_;
  Held map_;
  ScanTicket last_ticket_ = 0;
};

/// octovk.ColorMap: a Map holding a ColorMap (ColorOcTree).
class PyColorMap : public Map {
 public:
  PyColorMap(py::object context, ColorMap map)
      : Map(std::move(context), Held(std::in_place_type<ColorMap>, std::move(map))) {}
};

/// octovk.StampedMap: a Map holding a StampedMap (OcTreeStamped).
class PyStampedMap : public Map {
 public:
  PyStampedMap(py::object context, StampedMap map)
      : Map(std::move(context), Held(std::in_place_type<StampedMap>, std::move(map))) {}
};

/// octovk.StoredMap: a map of a store with each scan committed (octovk::StoredMap), its
/// Context kept alive and its calls ordered by one lock, as a Map's.
class PyStoredMap {
 public:
  PyStoredMap(py::object context, StoredMap stored)
      : context_(std::move(context)), stored_(std::move(stored)) {}

  /// `work` on the StoredMap with the GIL released and the lock held.
  template <class Work>
  auto run(Work&& work) {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);
    return work(stored_);
  }
  const py::object& context() const { return context_; }
  /// The next scan index for a commit that names none: the scans this object committed.
  std::uint64_t nextScan() { return scans_++; }

 private:
  py::object context_;
  std::mutex mutex_;
  StoredMap stored_;
  std::uint64_t scans_ = 0;
};

/// octovk.StoreFollower.updates()'s iterator: the follower and how it looks at the store.
struct FollowIterator {
  py::object follower;  // the octovk.StoreFollower, kept alive
  double interval_s = 0.5;
  std::optional<std::uint64_t> until_seq;
};

}  // namespace octovk::python

OCTOVK_PYTHON_CHECKED_CLASS(octovk::python::FollowIterator)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::python::PyStoredMap)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::python::Map)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::python::PyColorMap)
OCTOVK_PYTHON_CHECKED_CLASS(octovk::python::PyStampedMap)
