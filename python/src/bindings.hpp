// The parts of the module, each binding one header of the library (include/octovk/*.hpp).
#pragma once

#include <pybind11/pybind11.h>

#include "checked.hpp"

namespace octovk::python {

namespace py = pybind11;

/// Context, DeviceInfo, devices(), default_context(), validation_message_count().
void bindContext(py::module_& m);
/// Pose, CellState (an IntEnum), CastRayBackend, ScanRays, ScanStats, StageTimes.
void bindTypes(py::module_& m);
/// Map: scans, streaming, queries, files, memory.
void bindMap(py::module_& m);
/// DistanceField: the exact distance field over a box of a Map, batched queries.
void bindDistance(py::module_& m);
/// read_scan_graph(), read_tum_sequence(), read_depth_png(), graph2tree_sensor_origin(),
/// key_to_coord(), coord_to_key().
void bindFiles(py::module_& m);

/// The process's default Context (octovk.default_context()), created on first use.
py::object defaultContext();

/// The file system's bytes for `path` (str, bytes or os.PathLike, as open() takes them). ValueError
/// naming `arg` for a path with a NUL byte, which the C library would cut short there.
std::string pathString(py::handle path, const char* arg);

}  // namespace octovk::python
