// The Python module `octovk`: thin over the C++ library, with OctoMap's names in Python's
// spelling. The stub python/octovk.pyi mirrors what is bound here (tests/test_api.py checks).
#include <pybind11/stl.h>

#include <cmath>
#include <optional>
#include <sstream>

#include "arrays.hpp"
#include "bindings.hpp"
#include "errors.hpp"
#include "octovk/octomap_io.hpp"
#include "octovk/tum_sequence.hpp"

namespace octovk::python {
namespace {

std::string vectorText(const Eigen::Vector3f& v) {
  std::ostringstream s;
  s << '(' << v.x() << ", " << v.y() << ", " << v.z() << ')';
  return s.str();
}

py::array_t<float> vectorArray(const Eigen::Vector3f& v) {
  return ownedArray(std::vector<float>{v.x(), v.y(), v.z()}, {3});
}

void checkResolution(double resolution) {
  if (!(resolution > 0.0) || !std::isfinite(resolution))
    throw py::value_error("resolution: expected the map's cell edge in metres (> 0, finite), got " +
                          std::to_string(resolution));
}

// `obj` as a numpy array (numpy arrays as they are; torch CPU tensors and sequences through
// np.asarray) whose last extent is 3.
py::array tripleArray(py::handle obj, const char* arg, const char* what) {
  py::object np = py::module_::import("numpy");
  py::array a;
  try {
    a = np.attr("asarray")(obj);
  } catch (const py::error_already_set&) {
    throw py::type_error(std::string(arg) + ": expected " + what + ", got " +
                         std::string(py::str(py::type::handle_of(obj).attr("__qualname__"))));
  }
  if (a.ndim() < 1 || a.shape(a.ndim() - 1) != 3)
    throw py::value_error(std::string(arg) + ": expected " + what + ", got shape " +
                          std::string(py::str(a.attr("shape"))));
  return a;
}

// The shape of `a` as a vector.
std::vector<py::ssize_t> shapeOf(const py::array& a) {
  return std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim());
}

py::object keyToCoordArray(double resolution, py::handle keys) {
  checkResolution(resolution);
  const char* what = "integer keys of shape (..., 3) (uint16, as Map.changed_keys() gives them)";
  const py::array a = tripleArray(keys, "keys", what);
  const char kind = a.dtype().kind();
  if (kind != 'i' && kind != 'u')
    throw py::type_error(std::string("keys: expected ") + what + ", got " +
                         std::string(py::str(a.dtype())) + " values");
  const auto k = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(a);
  const std::int64_t* in = k.data();
  const std::size_t n = static_cast<std::size_t>(k.size()) / 3;
  std::vector<float> coords(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    Key key;
    for (std::size_t c = 0; c < 3; ++c) {
      const std::int64_t v = in[3 * i + c];
      if (v < 0 || v > 65535)
        throw py::value_error("keys: key " + std::to_string(i) + " holds " + std::to_string(v) +
                              "; a key is 0 to 65535 per axis");
      key[c] = static_cast<std::uint16_t>(v);
    }
    const Eigen::Vector3f centre = keyToCoord(resolution, key);
    for (int c = 0; c < 3; ++c) coords[3 * i + static_cast<std::size_t>(c)] = centre[c];
  }
  return likeInput(keys, ownedArray(std::move(coords), shapeOf(a)));
}

py::object coordToKeyArray(double resolution, py::handle coords) {
  checkResolution(resolution);
  const char* what = "float32 (or float64) coordinates of shape (..., 3), in metres";
  const py::array a = tripleArray(coords, "coords", what);
  if (a.dtype().kind() != 'f')
    throw py::type_error(std::string("coords: expected ") + what + ", got " +
                         std::string(py::str(a.dtype())) + " values");
  // float, as the map reads points (OctoMap's point3d): the key of the cell a point lands in.
  const auto f = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a);
  const float* in = f.data();
  const std::size_t n = static_cast<std::size_t>(f.size()) / 3;
  std::vector<std::uint16_t> keys(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f p(in[3 * i], in[3 * i + 1], in[3 * i + 2]);
    const std::optional<Key> key = coordToKey(resolution, p);
    if (!key) {
      std::ostringstream why;
      why << "coords: point " << i << " (" << p.x() << ", " << p.y() << ", " << p.z()
          << ") is NaN or outside the key range at resolution " << resolution
          << " (each coordinate within +-" << 32768 * resolution << " m)";
      throw py::value_error(why.str());
    }
    for (std::size_t c = 0; c < 3; ++c) keys[3 * i + c] = (*key)[c];
  }
  py::array_t<std::uint16_t> out = ownedArray(std::move(keys), shapeOf(a));
  if (!isTorch(coords)) return out;
  // torch has no uint16 (before 2.3): the keys as int32, which holds every key.
  py::object torch = py::module_::import("torch");
  return torch.attr("from_numpy")(out.attr("astype")("int32"));
}

}  // namespace

std::string pathString(py::handle path, const char* arg) {
  const py::bytes encoded = py::module_::import("os").attr("fsencode")(path);
  std::string file = encoded;
  if (file.find('\0') != std::string::npos)
    throw py::value_error(std::string(arg) + ": " + std::string(py::repr(path)) +
                          " holds a NUL byte ('\\x00'), which no file name can hold: the file "
                          "would be the part before it (remove the NUL; open() refuses it too)");
  return file;
}

py::object defaultContext() {
  py::module_ module = py::module_::import("octovk");
  py::object context = module.attr("_default_context");
  if (context.is_none()) {
    std::unique_ptr<Context> made;
    {
      py::gil_scoped_release release;
      made = std::move(Context::create().value());
    }
    context = py::cast(std::move(made));
    module.attr("_default_context") = context;
  }
  return context;
}

void bindContext(py::module_& m) {
  py::class_<DeviceInfo>(m, "DeviceInfo", "A Vulkan device (octovk::DeviceInfo).")
      .def_readonly("name", &DeviceInfo::name)
      .def_readonly("type", &DeviceInfo::type, "'discrete GPU', 'integrated GPU', 'CPU', ...")
      .def_readonly("driver", &DeviceInfo::driver, "driver name and version")
      .def_readonly("index", &DeviceInfo::index)
      .def_readonly("memory_bytes", &DeviceInfo::memory_bytes)
      .def_readonly("ray_query", &DeviceInfo::ray_query,
                    "the device offers ray queries (castRay's ray-tracing backend)")
      .def_readonly("ray_tracing_pipeline", &DeviceInfo::ray_tracing_pipeline,
                    "the device offers ray-tracing pipelines (the ray-tracing backends' other "
                    "way, RT_PIPELINE; a Context enables them with ray_query)")
      .def_readonly("ray_query_enabled", &DeviceInfo::ray_query_enabled,
                    "ray queries are enabled on this Context's device")
      .def("__repr__", [](const DeviceInfo& d) {
        return "DeviceInfo(index=" + std::to_string(d.index) + ", name='" + d.name + "', type='" +
               d.type + "', driver='" + d.driver + "')";
      });

  py::class_<Context>(m, "Context",
                      "The Vulkan device every map of a process shares (octovk::Context).\n\n"
                      "Maps on different threads may share one Context. Each Map keeps its "
                      "Context alive.")
      .def(py::init([](py::object selector, bool enable_validation, bool enable_ray_query,
                       py::object device, py::object validation, py::object ray_query) {
             ContextOptions options;
             if (!device.is_none()) {
               warnDeprecated(
                   "Context(device=...) is deprecated: name it selector (C++'s "
                   "ContextOptions::selector; Context.device is the DeviceInfo); the old name "
                   "goes in the next release");
               if (selector.is_none()) selector = device;
             }
             if (!selector.is_none()) options.selector = py::str(selector);
             options.enable_validation =
                 renamed(enable_validation, validation, "validation", "enable_validation");
             options.enable_ray_query =
                 renamed(enable_ray_query, ray_query, "ray_query", "enable_ray_query");
             py::gil_scoped_release release;
             return std::move(Context::create(options).value());
           }),
           py::arg("selector") = py::none(), py::arg("enable_validation") = false,
           py::arg("enable_ray_query") = true, py::kw_only(), py::arg("device") = py::none(),
           py::arg("validation") = py::none(), py::arg("ray_query") = py::none(),
           "Opens a device (C++'s ContextOptions): `selector` is an index or a name substring "
           "(None: a real GPU when present, else lavapipe; the OCTOVK_DEVICE environment "
           "variable overrides). `enable_validation` runs every Vulkan call through the Khronos "
           "validation layer (slow; OCTOVK_VALIDATION=1 does too). `enable_ray_query=False` "
           "never uses ray queries. device, validation, ray_query: the deprecated names of "
           "selector, enable_validation, enable_ray_query. Raises NoDeviceError or "
           "MissingFeatureError with the reason.")
      .def_property_readonly("device", &Context::device, "The device (DeviceInfo).")
      .def("__repr__",
           [](const Context& c) { return "Context(device='" + c.device().name + "')"; });

  m.def("devices", &Context::listDevices, "Every usable Vulkan device (list of DeviceInfo).");
  m.def(
      "cpu_driver_threads",
      [] {
        const octovk::CpuDriverThreads t = octovk::cpuDriverThreads();
        return py::make_tuple(t.setting, t.chosen_by_octovk);
      },
      "LP_NUM_THREADS as the process holds it (lavapipe's worker threads; GPU drivers ignore it)\n"
      "and whether octovk chose it: (setting, chosen_by_octovk). Unset at import, octovk sets\n"
      "it to '0' (a scan is many small passes, which lavapipe's threads slow down); set it\n"
      "before importing octovk to choose.");
  m.def("default_context", &defaultContext,
        "The Context maps use when none is given, created on first use.");
  m.def("validation_message_count", &validationMessageCount,
        "Validation-layer messages received by every Context of this process so far.");
  m.def(
      "_last_input_address", [] { return lastInputAddress(); },
      "For tests: the address of the memory last handed to the library as points, pixels or "
      "query points (equal to the caller's array data: it was read in place).");
}

void bindTypes(py::module_& m) {
  // An IntEnum, not a pybind11 enum: search() returns states as uint8 arrays, which
  // `state == CellState.FREE` must compare as numbers (a pybind11 enum is no number to numpy).
  py::list states;
  for (const auto& [name, s] : {std::pair{"UNKNOWN", CellState::kUnknown},
                                {"FREE", CellState::kFree},
                                {"OCCUPIED", CellState::kOccupied}})
    states.append(py::make_tuple(name, static_cast<int>(s)));
  py::object cell_state = py::module_::import("enum").attr("IntEnum")(
      "CellState", states, py::arg("module") = m.attr("__name__"));
  cell_state.attr("__doc__") =
      "State of a cell as OctoMap's search() and isNodeOccupied() see it (an IntEnum): "
      "Map.search() returns these values as uint8, so `state == CellState.FREE` compares them.";
  m.attr("CellState") = cell_state;
  py::enum_<CastRayBackend>(m, "CastRayBackend", "How castRay is answered on the device.")
      .value("AUTO", CastRayBackend::kAuto, "ray tracing where available, else the walk")
      .value("WALK", CastRayBackend::kWalk, "a compute shader steps through every cell")
      .value("RAY_TRACING", CastRayBackend::kRayTracing,
             "rays traced against an acceleration structure: RAY_QUERY where the device has ray "
             "queries, else RT_PIPELINE")
      .value("RAY_QUERY", CastRayBackend::kRayQuery,
             "RAY_TRACING through ray queries (needs VK_KHR_ray_query)")
      .value("RT_PIPELINE", CastRayBackend::kRayTracingPipeline,
             "RAY_TRACING through a ray-tracing pipeline (needs VK_KHR_ray_tracing_pipeline)");
  py::enum_<ScanRays>(m, "ScanRays", "How a scan's rays find their cells.")
      .value("WALK", ScanRays::kWalk, "OctoMap's DDA through every cell")
      .value("RAY_TRACING", ScanRays::kRayTracing,
             "the DDA jumps over leaves already clamped free: RAY_QUERY where the device has ray "
             "queries, else RT_PIPELINE")
      .value("RAY_QUERY", ScanRays::kRayQuery,
             "RAY_TRACING through ray queries (needs VK_KHR_ray_query)")
      .value("RT_PIPELINE", ScanRays::kRayTracingPipeline,
             "RAY_TRACING through a ray-tracing pipeline (needs VK_KHR_ray_tracing_pipeline)");

  py::class_<Pose>(m, "Pose",
                   "A rigid transform with OctoMap's float arithmetic (octomath::Pose6D): "
                   "rotation q * v * q^-1 in single precision, then the translation.")
      .def(py::init([](py::handle translation, py::handle rotation) {
             Pose pose;
             pose.translation = toVector3(translation, "translation");
             pose.rotation = toQuaternion(rotation, "rotation");
             return pose;
           }),
           py::arg("translation") = py::make_tuple(0, 0, 0),
           py::arg("rotation") = py::make_tuple(0, 0, 0, 1),
           "translation: 3 numbers in metres; rotation: a unit quaternion x, y, z, w.")
      .def_static(
          "from_matrix", [](py::handle matrix) { return toPose(matrix, "matrix"); },
          py::arg("matrix"), "A Pose from a 4x4 rigid transform.")
      .def_property_readonly(
          "translation", [](const Pose& p) { return vectorArray(p.translation); },
          "float32 array (3,)")
      .def_property_readonly(
          "rotation",
          [](const Pose& p) {
            const auto& q = p.rotation;
            return ownedArray(std::vector<float>{q.x(), q.y(), q.z(), q.w()}, {4});
          },
          "the quaternion as a float32 array (4,): x, y, z, w")
      .def(
          "matrix",
          [](const Pose& p) {
            Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
            t.topLeftCorner<3, 3>() = p.rotation.cast<double>().toRotationMatrix();
            t.topRightCorner<3, 1>() = p.translation.cast<double>();
            std::vector<double> values(16);
            for (int r = 0; r < 4; ++r)
              for (int c = 0; c < 4; ++c) values[static_cast<std::size_t>(4 * r + c)] = t(r, c);
            return ownedArray(std::move(values), {4, 4});
          },
          "The 4x4 transform (float64).")
      .def("inverse", &Pose::inverse, "The inverse, bit-exact with octomath::Pose6D::inv.")
      .def(
          "transform",
          [](const Pose& p, py::handle point) {
            return vectorArray(p.transform(toVector3(point, "point")));
          },
          py::arg("point"), "The pose applied to one point (bit-exact with Pose6D::transform).")
      .def("__repr__", [](const Pose& p) {
        const auto& q = p.rotation;
        std::ostringstream s;
        s << "Pose(translation=" << vectorText(p.translation) << ", rotation=(" << q.x() << ", "
          << q.y() << ", " << q.z() << ", " << q.w() << "))";
        return s.str();
      });

  py::class_<StageTimes>(m, "StageTimes", "Device time of each stage of one scan, in ms.")
      .def_readonly("upload_ms", &StageTimes::upload_ms)
      .def_readonly("ray_keys_ms", &StageTimes::ray_keys_ms)
      .def_readonly("classify_ms", &StageTimes::classify_ms)
      .def_readonly("tree_update_ms", &StageTimes::tree_update_ms)
      .def_readonly("prune_ms", &StageTimes::prune_ms)
      .def_readonly("leaf_boxes_ms", &StageTimes::leaf_boxes_ms)
      .def_property_readonly("total_ms", &StageTimes::total_ms);

  py::class_<ScanStats>(m, "ScanStats", "What one scan did (octovk::ScanStats).")
      .def_readonly("ticket", &ScanStats::ticket, "the scan's place in the map's order")
      .def_readonly("points", &ScanStats::points, "points given (a depth image: its pixels)")
      .def_readonly("skipped_nonfinite", &ScanStats::skipped_nonfinite)
      .def_readonly("skipped_outside", &ScanStats::skipped_outside)
      .def_readonly("skipped_no_depth", &ScanStats::skipped_no_depth)
      .def_readonly("free_cells", &ScanStats::free_cells)
      .def_readonly("occupied_cells", &ScanStats::occupied_cells)
      .def_readonly("aborted_cells", &ScanStats::aborted_cells)
      .def_readonly("nodes", &ScanStats::nodes, "nodes in the tree after the scan")
      .def_readonly("cell_set_attempts", &ScanStats::cell_set_attempts)
      .def_readonly("tile_groups", &ScanStats::tile_groups,
                    "parts the scan was applied in (groups of tiles): more than 1 where its "
                    "cells did not fit the device memory at once")
      .def_readonly("wall_ms", &ScanStats::wall_ms)
      .def_readonly("device", &ScanStats::device, "StageTimes")
      .def("__repr__", [](const ScanStats& s) {
        return "ScanStats(ticket=" + std::to_string(s.ticket) +
               ", points=" + std::to_string(s.points) +
               ", free_cells=" + std::to_string(s.free_cells) +
               ", occupied_cells=" + std::to_string(s.occupied_cells) +
               ", nodes=" + std::to_string(s.nodes) + ")";
      });
}

void bindFiles(py::module_& m) {
  m.def(
      "read_scan_graph",
      [](py::handle path) {
        const std::string file = pathString(path, "path");
        std::vector<GraphScan> scans;
        {
          py::gil_scoped_release release;
          scans = readScanGraph(file);
        }
        py::list out;
        for (GraphScan& scan : scans) {
          const auto n = static_cast<py::ssize_t>(scan.points_sensor.size());
          auto* heap = new std::vector<Eigen::Vector3f>(std::move(scan.points_sensor));
          py::capsule owner(heap,
                            [](void* p) { delete static_cast<std::vector<Eigen::Vector3f>*>(p); });
          py::array_t<float> points({n, py::ssize_t{3}},
                                    reinterpret_cast<const float*>(heap->data()), owner);
          out.append(py::make_tuple(points, scan.T_world_sensor));
        }
        return out;
      },
      py::arg("path"),
      "Reads the OctoMap scan graph (.graph) at path: a list of (points, pose) with points a "
      "float32 "
      "array (N, 3) in the sensor frame and pose the sensor's Pose in the world. Raises "
      "FormatError naming the file for a corrupt one.");
  m.def(
      "read_tum_sequence",
      [](py::handle dir, double max_time_difference_s, py::handle max_time_difference) {
        max_time_difference_s = renamed(max_time_difference_s, max_time_difference,
                                        "max_time_difference", "max_time_difference_s");
        const std::string folder = pathString(dir, "dir");
        TumSequence sequence;
        {
          py::gil_scoped_release release;
          sequence = readTumSequence(folder, max_time_difference_s);
        }
        py::list frames;
        for (const TumFrame& f : sequence.frames)
          frames.append(py::make_tuple(f.timestamp, f.image_path, f.T_world_camera));
        return frames;
      },
      py::arg("dir"), py::arg("max_time_difference_s") = kTumMaxTimeDifference, py::kw_only(),
      py::arg("max_time_difference") = py::none(),
      "The images of the TUM RGB-D folder dir that have a ground-truth pose, in depth.txt's "
      "order: a list of (timestamp, image path, T_world_camera Pose). Each image takes the pose "
      "nearest in time; images with none closer than max_time_difference_s seconds are left "
      "out (max_time_difference: its deprecated name). Raises IoError / FormatError naming the "
      "file and line.");
  m.def("key_to_coord", &keyToCoordArray, py::arg("resolution"), py::arg("keys"),
        "OctoMap's keyToCoord at the finest depth, for many keys (C++'s octovk::keyToCoord): "
        "the centre of each key's cell, per axis (key - 32768 + 0.5) * resolution. keys: "
        "integers of shape (..., 3), e.g. the uint16 keys Map.changed_keys() returns; "
        "resolution: the map's, in metres (Map.resolution). Returns float32 coordinates of the "
        "keys' shape (a torch tensor for a torch input). ValueError for a key outside 0 to "
        "65535.");
  m.def("coord_to_key", &coordToKeyArray, py::arg("resolution"), py::arg("coords"),
        "OctoMap's coordToKeyChecked at the finest depth, for many points (C++'s "
        "octovk::coordToKey): the key of the cell each point lands in, per axis "
        "floor(coordinate / resolution) + 32768, the coordinate taken as float32 as the map "
        "reads points. coords: floats of shape (..., 3), metres; resolution: the map's "
        "(Map.resolution). Returns uint16 keys of that shape (torch: int32, which torch has). "
        "ValueError naming the first point that is NaN or outside the key range.");
  m.def(
      "read_depth_png",
      [](py::handle path) {
        const std::string file = pathString(path, "path");
        DepthPng png;
        {
          py::gil_scoped_release release;
          png = readDepthPng(file);
        }
        return ownedArray(std::move(png.depths), {static_cast<py::ssize_t>(png.height),
                                                  static_cast<py::ssize_t>(png.width)});
      },
      py::arg("path"),
      "The 16-bit grayscale PNG depth image at path (TUM's format) as a uint16 array (H, W). "
      "Raises FormatError for another bit depth or colour type, or a corrupt file.");
  m.def(
      "graph2tree_sensor_origin",
      [](const Pose& pose) { return vectorArray(graph2treeSensorOrigin(pose)); }, py::arg("pose"),
      "The sensor origin OctoMap's graph2tree passes with a scan's pose (in the sensor frame): "
      "pose.inverse().transform(pose.translation).");
}

}  // namespace octovk::python

PYBIND11_MODULE(octovk, m) {
  using namespace octovk::python;
  m.doc() =
      "octovk: an OctoMap-compatible occupancy octree on a Vulkan device.\n\n"
      "    import numpy as np, octovk\n"
      "    m = octovk.Map(resolution=0.05)\n"
      "    m.insert_point_cloud(points, origin=(0, 0, 0))   # float32 (N, 3), world frame\n"
      "    state, log_odds, depth = m.search(queries)\n"
      "    m.write('map.bt')\n\n"
      "Inputs are read in place (numpy arrays, torch CPU tensors: the buffer protocol or "
      "__dlpack__); outputs are numpy arrays (buffer protocol and __dlpack__), or torch tensors "
      "sharing their memory where a query was given a tensor. Names are the C++ library's in "
      "snake_case, with their units (max_range_m). Errors of the library are octovk.Error "
      "subclasses.";
  // Before any Context loads the driver: a scan is many small passes, which lavapipe's worker
  // threads slow down (octovk::preferCpuDriverThreads); the user's LP_NUM_THREADS wins.
  octovk::preferCpuDriverThreads(0);
  m.attr("__version__") = OCTOVK_VERSION;
  m.attr("_default_context") = py::none();
  bindErrors(m);
  bindContext(m);
  bindTypes(m);
  bindMap(m);
  bindDistance(m);
  bindFiles(m);
}
