// The Python module `octovk`: thin over the C++ library, with OctoMap's names in Python's
// spelling. The stub python/octovk.pyi mirrors what is bound here (tests/test_api.py checks).
#include <pybind11/stl.h>

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
      .def(py::init([](py::object device, bool validation, bool ray_query) {
             ContextOptions options;
             if (!device.is_none()) options.selector = py::str(device);
             options.enable_validation = validation;
             options.enable_ray_query = ray_query;
             py::gil_scoped_release release;
             return std::move(Context::create(options).value());
           }),
           py::arg("device") = py::none(), py::arg("validation") = false,
           py::arg("ray_query") = true,
           "Opens a device: `device` is an index or a name substring (None: a real GPU when "
           "present, else lavapipe; the OCTOVK_DEVICE environment variable overrides). "
           "`validation` runs every Vulkan call through the Khronos validation layer (slow; "
           "OCTOVK_VALIDATION=1 does too). `ray_query=False` never uses ray queries. Raises "
           "NoDeviceError or MissingFeatureError with the reason.")
      .def_property_readonly("device", &Context::device, "The device (DeviceInfo).")
      .def("__repr__",
           [](const Context& c) { return "Context(device='" + c.device().name + "')"; });

  m.def("devices", &Context::listDevices, "Every usable Vulkan device (list of DeviceInfo).");
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
      .def_property_readonly("total_ms", &StageTimes::total);

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
      [](py::handle dir, double max_time_difference) {
        const std::string folder = pathString(dir, "dir");
        TumSequence sequence;
        {
          py::gil_scoped_release release;
          sequence = readTumSequence(folder, max_time_difference);
        }
        py::list frames;
        for (const TumFrame& f : sequence.frames)
          frames.append(py::make_tuple(f.timestamp, f.image_path, f.T_world_camera));
        return frames;
      },
      py::arg("dir"), py::arg("max_time_difference") = kTumMaxTimeDifference,
      "The images of the TUM RGB-D folder dir that have a ground-truth pose, in depth.txt's "
      "order: a list of (timestamp, image path, T_world_camera Pose). Each image takes the pose "
      "nearest in time; images with none closer than max_time_difference seconds are left "
      "out. Raises IoError / FormatError naming the file and line.");
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
      "__dlpack__); outputs are numpy arrays (buffer protocol and __dlpack__). Errors of the "
      "library are octovk.Error subclasses.";
  m.attr("__version__") = OCTOVK_VERSION;
  m.attr("_default_context") = py::none();
  bindErrors(m);
  bindContext(m);
  bindTypes(m);
  bindMap(m);
  bindDistance(m);
  bindFiles(m);
}
