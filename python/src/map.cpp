// octovk.Map: the OccupancyMap with its Context, one lock, and the GIL released for device work.
#include "map.hpp"

#include <pybind11/eval.h>
#include <pybind11/stl.h>

#include <ctime>
#include <optional>

#include "arrays.hpp"
#include "bindings.hpp"
#include "octovk/octomap_io.hpp"
#include "octovk/store.hpp"

namespace octovk::python {
namespace {

// The range a scan or ray takes: max_range_m, or the deprecated `max_range` where given.
double rangeOf(double max_range_m, py::handle max_range) {
  return renamed(max_range_m, max_range, "max_range", "max_range_m",
                 "metres, as C++'s ScanOptions::max_range_m and Ray::max_range_m");
}

ScanOptions scanOptions(double max_range_m, py::handle max_range, bool discretize) {
  return ScanOptions{.max_range_m = rangeOf(max_range_m, max_range), .discretize = discretize};
}

Context& contextOf(const py::object& context) { return context.cast<Context&>(); }

py::object orDefault(py::object context) {
  return context.is_none() ? defaultContext() : std::move(context);
}

DepthImage depthImage(const ArrayView& depth, float fx, float fy, float cx, float cy,
                      float depth_scale) {
  DepthImage image;
  image.height = static_cast<std::uint32_t>(depth.extent(0));
  image.width = static_cast<std::uint32_t>(depth.extent(1));
  const std::size_t n = depth.size();
  if (depth.dtype() == DType::kUint16) {
    image.encoding = DepthImage::Encoding::kUint16;
    image.depths =
        std::span<const std::uint16_t>(static_cast<const std::uint16_t*>(depth.data()), n);
  } else {
    image.encoding = DepthImage::Encoding::kFloat32;
    image.depths = std::span<const float>(static_cast<const float*>(depth.data()), n);
  }
  image.fx = fx;
  image.fy = fy;
  image.cx = cx;
  image.cy = cy;
  image.depth_scale = depth_scale;
  return image;
}

// A whole number of seconds for a stamp argument (`arg`): an int from 0 to 2**32 - 1 (numpy
// integers too), or None for the clock's now (time(NULL), as OcTreeStamped takes it).
std::uint32_t secondsOf(py::handle value, const char* arg) {
  if (value.is_none()) return static_cast<std::uint32_t>(std::time(nullptr));
  const std::string why = std::string(arg) +
                          ": expected whole seconds, an int from 0 to 2**32 - 1 (as "
                          "int(time.time()) gives them), got ";
  // bool is an int to Python, but True as a time is a slip.
  if (PyBool_Check(value.ptr()) || !PyIndex_Check(value.ptr()))
    throw py::value_error(why + std::string(py::repr(value)));
  const auto seconds = py::reinterpret_steal<py::object>(PyNumber_Index(value.ptr()));
  if (!seconds) throw py::error_already_set();
  if (seconds < py::int_(0) || seconds > py::int_(0xFFFFFFFFull))
    throw py::value_error(why + std::string(py::repr(seconds)));
  return seconds.cast<std::uint32_t>();
}

ColorFold colorFoldOf(const std::string& fold) {
  if (fold == "average") return ColorFold::kAverage;
  if (fold == "integrate") return ColorFold::kIntegrate;
  throw py::value_error(
      "color_fold: expected 'average' (ColorOcTree::averageNodeColor) or "
      "'integrate' (integrateNodeColor), got '" +
      fold + "'");
}

// A scan's colours (ColorMap): `colors` None (no colour), or uint8 with one r, g, b per point or
// pixel, of shape `lead` + (3,); read in place while it lives, or copied where its strides ask
// for it (the library copies the colours before the call returns anyway).
class ScanColors {
  static constexpr const char* kColorsAre =
      " (colors: one uint8 r, g, b from 0 to 255 per point, or per pixel of a depth image; "
      "floats from 0 to 1 become (colors * 255).round().astype(np.uint8))";

 public:
  ScanColors(py::handle colors, const std::string& fold, const std::vector<py::ssize_t>& lead,
             Copy copy)
      : fold_(colorFoldOf(fold)) {
    if (colors.is_none()) return;
    const auto dtypes = std::initializer_list<DType>{DType::kUint8};
    try {
      if (lead.size() == 1)
        view_.emplace(colors, "colors", dtypes, std::initializer_list<std::ptrdiff_t>{lead[0], 3},
                      false, copy);
      else
        view_.emplace(colors, "colors", dtypes,
                      std::initializer_list<std::ptrdiff_t>{lead[0], lead[1], 3}, false, copy);
    } catch (const py::type_error& e) {
      throw py::type_error(std::string(e.what()) + kColorsAre);
    } catch (const py::value_error& e) {
      throw py::value_error(std::string(e.what()) + kColorsAre);
    }
  }

  void applyTo(ScanOptions& options) const {
    static_assert(sizeof(Rgb) == 3 && alignof(Rgb) == 1);
    options.color_fold = fold_;
    if (view_) options.colors = {static_cast<const Rgb*>(view_->data()), view_->size() / 3};
  }

 private:
  ColorFold fold_;
  std::optional<ArrayView> view_;
};

// A point cloud scan's arguments, checked and read in place: Map.insert_point_cloud and
// submit_point_cloud, and their ColorMap and StampedMap forms (colors, stamp).
class PointScan {
 public:
  PointScan(py::handle points, py::handle origin, py::handle pose, double max_range_m,
            bool discretize, bool copy, py::handle max_range)
      : points_(points, "points", Layout::kPoints, {DType::kFloat32}, copyArgument(copy)),
        origin_(toVector3(origin, "origin")),
        posed_(!pose.is_none()),
        pose_(toPose(pose, "pose")),
        options_(scanOptions(max_range_m, max_range, discretize)) {}

  void colors(py::handle colors, const std::string& fold) {
    colors_.emplace(colors, fold, points_.leading(), Copy::kAllowed);
    colors_->applyTo(options_);
  }
  void stamp(py::handle stamp) { options_.stamp = secondsOf(stamp, "stamp"); }

  ScanStats insert(OccupancyMap& map) const {
    return posed_ ? map.insertPointCloud(points_.points(), origin_, pose_, options_)
                  : map.insertPointCloud(points_.points(), origin_, options_);
  }
  ScanTicket submit(OccupancyMap& map) const {
    return posed_ ? map.submitPointCloud(points_.points(), origin_, pose_, options_)
                  : map.submitPointCloud(points_.points(), origin_, options_);
  }
  const void* data() const { return points_.data(); }

 private:
  const ArrayView points_;
  const Eigen::Vector3f origin_;
  const bool posed_;
  const Pose pose_;
  ScanOptions options_;
  std::optional<ScanColors> colors_;
};

// A depth image scan's arguments, as PointScan's: colors are one per pixel, (H, W, 3).
class DepthScan {
 public:
  DepthScan(py::handle depth, float fx, float fy, float cx, float cy, float depth_scale,
            py::handle pose, double max_range_m, bool discretize, py::handle max_range)
      : pixels_(depth, "depth", Layout::kDepth, {DType::kFloat32, DType::kUint16}),
        image_(depthImage(pixels_, fx, fy, cx, cy, depth_scale)),
        pose_(toPose(pose, "pose")),
        options_(scanOptions(max_range_m, max_range, discretize)) {}

  void colors(py::handle colors, const std::string& fold) {
    colors_.emplace(colors, fold,
                    std::vector<py::ssize_t>{static_cast<py::ssize_t>(image_.height),
                                             static_cast<py::ssize_t>(image_.width)},
                    Copy::kAllowed);
    colors_->applyTo(options_);
  }
  void stamp(py::handle stamp) { options_.stamp = secondsOf(stamp, "stamp"); }

  ScanStats insert(OccupancyMap& map) const {
    return map.insertDepthImage(image_, pose_, options_);
  }
  ScanTicket submit(OccupancyMap& map) const {
    return map.submitDepthImage(image_, pose_, options_);
  }
  const void* data() const { return pixels_.data(); }

 private:
  const ArrayView pixels_;
  const DepthImage image_;
  const Pose pose_;
  ScanOptions options_;
  std::optional<ScanColors> colors_;
};

// One result column of `shape`: the caller's `out` array (checked) or a new one.
template <class T>
py::object resultColumn(py::handle out, const char* name, DType dtype,
                        std::vector<py::ssize_t> shape, std::optional<ArrayView>& view) {
  py::object array =
      out.is_none() ? py::object(py::array_t<T>(shape)) : py::reinterpret_borrow<py::object>(out);
  // ArrayView takes a fixed shape as an initializer_list: at most 3 extents here.
  const std::vector<std::ptrdiff_t> want(shape.begin(), shape.end());
  const auto dtypes = std::initializer_list<DType>{dtype};
  switch (want.size()) {
    case 1:
      view.emplace(array, name, dtypes, std::initializer_list<std::ptrdiff_t>{want[0]}, true);
      break;
    case 2:
      view.emplace(array, name, dtypes, std::initializer_list<std::ptrdiff_t>{want[0], want[1]},
                   true);
      break;
    default:
      view.emplace(array, name, dtypes,
                   std::initializer_list<std::ptrdiff_t>{want[0], want[1], want[2]}, true);
  }
  return array;
}

// `lead` with `extent` appended.
std::vector<py::ssize_t> withExtent(std::vector<py::ssize_t> lead, py::ssize_t extent) {
  lead.push_back(extent);
  return lead;
}

// The results of a query on `input`: the caller's out arrays where given, else the new arrays
// as the caller's library has them (torch tensors for a torch input, sharing their memory).
py::tuple queryResults(py::handle input, bool given, const std::vector<py::object>& results) {
  py::tuple t(results.size());
  for (std::size_t i = 0; i < results.size(); ++i)
    t[i] = given ? results[i] : likeInput(input, results[i]);
  return t;
}

// `out` as a tuple of `n` arrays, or None.
py::tuple outTuple(py::handle out, std::size_t n, const char* what) {
  if (out.is_none()) {
    py::tuple nones(n);
    for (std::size_t i = 0; i < n; ++i) nones[i] = py::none();
    return nones;
  }
  if (!py::isinstance<py::tuple>(out) && !py::isinstance<py::list>(out))
    throw py::type_error(std::string("out: expected a tuple ") + what);
  py::tuple t = py::tuple(py::reinterpret_borrow<py::object>(out));
  if (t.size() != n) throw py::value_error(std::string("out: expected a tuple ") + what);
  for (std::size_t i = 0; i < n; ++i)
    if (t[i].is_none()) throw py::type_error(std::string("out: expected a tuple ") + what);
  return t;
}

py::tuple leafArrays(std::vector<OccupancyMap::LeafBoxHost>&& leaves) {
  using Leaf = OccupancyMap::LeafBoxHost;
  static_assert(sizeof(Leaf) == 5 * sizeof(float));
  const auto n = static_cast<py::ssize_t>(leaves.size());
  auto* heap = new std::vector<Leaf>(std::move(leaves));
  py::capsule owner(heap, [](void* p) { delete static_cast<std::vector<Leaf>*>(p); });
  const auto* base = reinterpret_cast<const char*>(heap->data());
  constexpr py::ssize_t kStride = sizeof(Leaf);
  constexpr py::ssize_t kFloat = sizeof(float);
  py::array_t<float> centers({n, py::ssize_t{3}}, {kStride, kFloat},
                             reinterpret_cast<const float*>(base + offsetof(Leaf, center)), owner);
  py::array_t<float> sizes({n}, {kStride},
                           reinterpret_cast<const float*>(base + offsetof(Leaf, size)), owner);
  py::array_t<float> log_odds(
      {n}, {kStride}, reinterpret_cast<const float*>(base + offsetof(Leaf, log_odds)), owner);
  return py::make_tuple(centers, sizes, log_odds);
}

// An array of origins ((N, 3), (H, W, 3), ...), or one origin (3 numbers) for every ray.
bool isPointArray(py::handle obj) {
  if (!py::hasattr(obj, "shape")) return false;
  try {
    return py::len(obj.attr("shape")) >= 2;
  } catch (const py::error_already_set&) {
    return false;
  }
}

// Map.device_bytes()'s result: the total, an int, whose breakdown fields (device_bytes() returned
// a DeviceBytes before) still answer for one release, with a DeprecationWarning.
py::object deviceBytesTotal(const OccupancyMap::DeviceBytes& bytes) {
  static py::object* type = [] {
    py::dict scope;
    py::exec(R"py(
import warnings
class DeviceBytesTotal(int):
    """Map.device_bytes(): device bytes the map holds, an int (C++'s deviceBytes()). Its fields
    pool, leaf_boxes, ..., total are deprecated (device_bytes() returned the breakdown before):
    use Map.device_bytes_by_use()."""
    def __new__(cls, by_use):
        self = int.__new__(cls, by_use.total)
        self._by_use = by_use
        return self
    def __getattr__(self, name):
        if name.startswith("_") or not hasattr(type(self._by_use), name):
            raise AttributeError(name)
        warnings.warn("device_bytes() is the total, an int, as C++'s deviceBytes(); for its "
                      f"breakdown use device_bytes_by_use().{name} (device_bytes().{name} goes "
                      "in the next release)", DeprecationWarning, stacklevel=2)
        return getattr(self._by_use, name)
)py",
             scope);
    auto* made = new py::object(scope["DeviceBytesTotal"]);  // lives as long as the interpreter
    made->attr("__module__") = "octovk";
    return made;
  }();
  return (*type)(bytes);
}

constexpr const char* kMapDoc =
    "An OctoMap-compatible occupancy octree held on a Vulkan device (octovk::OccupancyMap).\n\n"
    "Its scans and queries give OctoMap's answers bit for bit (OcTree with lazy_eval=False). "
    "Points are float32 arrays of shape (N, 3), organised clouds (H, W, 3) or (N, 4) with x, "
    "y, z first (numpy arrays or torch CPU tensors; C-contiguous (N, 3) and (H, W, 3) are read "
    "in place, never copied; (N, 4) and other strides, such as xyz = P4[:, :3], are copied "
    "only with copy=True); depth images float32 or uint16 (H, W) or (1, H, W); 3-vectors any "
    "3 numbers; poses an octovk.Pose, a 4x4 rigid transform or (translation, quaternion x y z "
    "w). Query results are numpy arrays (buffer protocol and __dlpack__), or torch tensors "
    "sharing their memory when the query's input is a torch tensor.\n\n"
    "Names are C++'s in snake_case, with units as there (max_range_m). Properties never wait "
    "for the device nor raise (the parameters, context, scans_in_flight); every call that reads "
    "the map (node_count(), search(), ...) is a method: it first waits for the submitted scans "
    "and may raise a scan's error.\n\n"
    "The GIL is released while the device works; one thread at a time uses a map (calls from "
    "several threads are serialised). A map keeps its Context alive. Library errors raise "
    "octovk.Error subclasses; a call that raises leaves the map as it was.\n\n"
    "ColorMap and StampedMap (OctoMap's ColorOcTree and OcTreeStamped) are Maps whose nodes "
    "also hold a colour or a time stamp.";

// MapParams of `resolution` and OctoMap's sensor model as the keyword arguments give it.
MapParams sensorParams(double resolution, double prob_hit, double prob_miss, double clamping_min,
                       double clamping_max, double occupancy_threshold) {
  MapParams params;
  params.resolution = resolution;
  params.prob_hit = prob_hit;
  params.prob_miss = prob_miss;
  params.clamping_min = clamping_min;
  params.clamping_max = clamping_max;
  params.occupancy_threshold = occupancy_threshold;
  return params;
}

// Binds `cls`'s constructor: an empty Self holding a Kind (OccupancyMap, ColorMap, StampedMap)
// made from the keywords every map takes; `doc` starts the docstring.
template <class Self, class Kind, class Class>
void defInit(Class& cls, const char* doc) {
  cls.def(py::init([](double resolution, double prob_hit, double prob_miss, double clamping_min,
                      double clamping_max, double occupancy_threshold, std::size_t max_nodes,
                      std::size_t max_device_bytes, CastRayBackend cast_ray_backend,
                      ScanRays scan_rays, py::object context) {
            MapParams params = sensorParams(resolution, prob_hit, prob_miss, clamping_min,
                                            clamping_max, occupancy_threshold);
            params.max_nodes = max_nodes;
            params.max_device_bytes = max_device_bytes;
            params.cast_ray_backend = cast_ray_backend;
            params.scan_rays = scan_rays;
            context = orDefault(std::move(context));
            Context& ctx = contextOf(context);
            std::optional<Kind> made;
            {
              py::gil_scoped_release release;
              made.emplace(ctx, params);
            }
            return std::make_unique<Self>(std::move(context), std::move(*made));
          }),
          py::arg("resolution") = 0.1, py::kw_only(), py::arg("prob_hit") = 0.7,
          py::arg("prob_miss") = 0.4, py::arg("clamping_min") = 0.1192,
          py::arg("clamping_max") = 0.971, py::arg("occupancy_threshold") = 0.5,
          py::arg("max_nodes") = 0, py::arg("max_device_bytes") = 0,
          py::arg("cast_ray_backend") = CastRayBackend::kAuto,
          py::arg("scan_rays") = ScanRays::kWalk, py::arg("context") = py::none(),
          (std::string(doc) +
           " resolution: edge of the finest cells in metres; prob_hit, prob_miss, "
           "clamping_min, clamping_max, occupancy_threshold: OctoMap's sensor model (its "
           "defaults); max_nodes / max_device_bytes cap the node pool / everything the map holds "
           "on the device (0: no cap); cast_ray_backend: how cast_rays runs (AUTO: ray tracing "
           "where the device has it); scan_rays: how scans find their cells; context: a Context "
           "(None: default_context()). Raises InvalidArgumentError naming a bad value.")
              .c_str());
}

// A map as the Python class of its tree type: Map, ColorMap or StampedMap.
py::object asMapClass(py::object context, OccupancyMap&& made) {
  switch (made.params().payload) {
    case Payload::kColor:
      return py::cast(std::make_unique<PyColorMap>(context, ColorMap(std::move(made))));
    case Payload::kStamp:
      return py::cast(std::make_unique<PyStampedMap>(context, StampedMap(std::move(made))));
    case Payload::kNone:
      break;
  }
  return py::cast(std::make_unique<Map>(context, std::move(made)));
}

// The map in `path` as the class of its tree type (params().payload): Map, ColorMap or
// StampedMap; with `want`, a FormatError where the file holds another tree type.
py::object readMap(py::handle path, py::object context, std::size_t max_device_bytes,
                   std::optional<Payload> want) {
  const std::string file = pathString(path, "path");
  context = orDefault(std::move(context));
  Context& ctx = contextOf(context);
  std::optional<OccupancyMap> made;
  {
    py::gil_scoped_release release;
    made.emplace(readMapFile(ctx, file, max_device_bytes));
  }
  const Payload payload = made->params().payload;
  if (want && payload != *want)
    throw Error(ErrorCode::kFormat, file + ": its tree type is " + treeTypeName(payload) +
                                        ", not " + treeTypeName(*want) +
                                        "; octovk.Map.read(path) reads every tree type, as the "
                                        "class it names");
  return asMapClass(std::move(context), std::move(*made));
}

// The static `read` of a map class: readMap with that class's tree type (none: any).
template <typename Class>
void defRead(Class& cls, std::optional<Payload> want, const char* doc) {
  cls.def_static(
      "read",
      [want](py::handle path, py::object context, std::size_t max_device_bytes) {
        return readMap(path, std::move(context), max_device_bytes, want);
      },
      py::arg("path"), py::kw_only(), py::arg("context") = py::none(),
      py::arg("max_device_bytes") = 0, doc);
}

constexpr const char* kColorMapDoc =
    "OctoMap's ColorOcTree on a Vulkan device (octovk::ColorMap): a Map whose nodes also hold a "
    "colour, and everything a Map offers.\n\n"
    "A scan with colors (uint8, one r, g, b per point) is inserted as ColorOcTree's "
    "insertPointCloud, then each point's colour is folded into the node search() finds for it, "
    "in the cloud's order: averageNodeColor (color_fold='average': a node without colour takes "
    "it, a coloured one the integer mean) or integrateNodeColor ('integrate'). White "
    "(255, 255, 255) is OctoMap's 'no colour yet'. Files written are ColorOcTree .ot files "
    "(a .bt holds no colour); Map.read returns a ColorMap for them.";

constexpr const char* kStampedMapDoc =
    "OctoMap's OcTreeStamped on a Vulkan device (octovk::StampedMap): a Map whose nodes also "
    "hold a time stamp in whole seconds, and everything a Map offers.\n\n"
    "Every leaf a scan updates takes the scan's stamp (stamp=, OcTreeStamped's time(NULL); "
    "None: the clock's now); degrade_outdated() gives occupied leaves older than a threshold one "
    "miss, as degradeOutdatedNodes. Children merge only where their log-odds and stamps are "
    "equal. Map.read returns a StampedMap for an OcTreeStamped file.";

constexpr const char* kColorsDoc =
    " colors: None (no colour) or uint8 with one r, g, b per point, of the points' shape with 3 "
    "last ((N, 3), or (H, W, 3) for an organised cloud; read in place, copied where not "
    "C-contiguous); color_fold: 'average' (ColorOcTree::averageNodeColor) or 'integrate' "
    "(integrateNodeColor).";

void bindColorMap(py::module_& m) {
  py::class_<PyColorMap, Map> cls(m, "ColorMap", kColorMapDoc);
  defInit<PyColorMap, ColorMap>(cls, "An empty colour map (ColorOcTree).");
  defRead(cls, Payload::kColor,
          "A new ColorMap from an OctoMap ColorOcTree .ot file; FormatError for another tree type "
          "(Map.read reads every type). context and max_device_bytes as in Map.read.");

  cls.def(
      "insert_point_cloud",
      [](PyColorMap& self, py::handle points, py::handle origin, py::handle pose,
         double max_range_m, bool discretize, py::handle colors, const std::string& color_fold,
         bool copy, py::handle max_range) {
        PointScan scan(points, origin, pose, max_range_m, discretize, copy, max_range);
        scan.colors(colors, color_fold);
        noteInput(scan.data());
        return self.run([&](OccupancyMap& map) { return scan.insert(map); });
      },
      py::arg("points"), py::arg("origin"), py::arg("pose") = py::none(),
      py::arg("max_range_m") = -1.0, py::arg("discretize") = false, py::kw_only(),
      py::arg("colors") = py::none(), py::arg("color_fold") = "average", py::arg("copy") = false,
      py::arg("max_range") = py::none(),
      (std::string("Map.insert_point_cloud (points, origin, pose, max_range_m, discretize, "
                   "copy, max_range as there), then each point's colour folded into its node.") +
       kColorsDoc + " Returns ScanStats.")
          .c_str());
  cls.def(
      "submit_point_cloud",
      [](PyColorMap& self, py::handle points, py::handle origin, py::handle pose,
         double max_range_m, bool discretize, py::handle colors, const std::string& color_fold,
         bool copy, py::handle max_range) {
        PointScan scan(points, origin, pose, max_range_m, discretize, copy, max_range);
        scan.colors(colors, color_fold);
        noteInput(scan.data());
        const ScanTicket ticket = self.run([&](OccupancyMap& map) { return scan.submit(map); });
        self.noteTicket(ticket);
        return ticket;
      },
      py::arg("points"), py::arg("origin"), py::arg("pose") = py::none(),
      py::arg("max_range_m") = -1.0, py::arg("discretize") = false, py::kw_only(),
      py::arg("colors") = py::none(), py::arg("color_fold") = "average", py::arg("copy") = false,
      py::arg("max_range") = py::none(),
      (std::string("insert_point_cloud(points, origin, pose, max_range_m, discretize, colors, "
                   "color_fold, copy, max_range) without waiting (points and colours are "
                   "copied before it returns). Returns the scan's ticket.") +
       kColorsDoc)
          .c_str());
  cls.def(
      "insert_depth_image",
      [](PyColorMap& self, py::handle depth, float fx, float fy, float cx, float cy,
         float depth_scale, py::handle pose, double max_range_m, bool discretize, py::handle colors,
         const std::string& color_fold, py::handle max_range) {
        DepthScan scan(depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, discretize,
                       max_range);
        scan.colors(colors, color_fold);
        noteInput(scan.data());
        return self.run([&](OccupancyMap& map) { return scan.insert(map); });
      },
      py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
      py::arg("depth_scale"), py::arg("pose") = py::none(), py::arg("max_range_m") = -1.0,
      py::arg("discretize") = false, py::kw_only(), py::arg("colors") = py::none(),
      py::arg("color_fold") = "average", py::arg("max_range") = py::none(),
      "Map.insert_depth_image (depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, "
      "discretize, max_range as there), then each pixel's colour folded into the node of its "
      "point, row by row (skipped pixels fold nothing). colors: None or uint8 (H, W, 3), one "
      "r, g, b per pixel (an RGB image registered to the depth image); color_fold: 'average' "
      "or 'integrate', as in insert_point_cloud. Returns ScanStats.");
  cls.def(
      "submit_depth_image",
      [](PyColorMap& self, py::handle depth, float fx, float fy, float cx, float cy,
         float depth_scale, py::handle pose, double max_range_m, bool discretize, py::handle colors,
         const std::string& color_fold, py::handle max_range) {
        DepthScan scan(depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, discretize,
                       max_range);
        scan.colors(colors, color_fold);
        noteInput(scan.data());
        const ScanTicket ticket = self.run([&](OccupancyMap& map) { return scan.submit(map); });
        self.noteTicket(ticket);
        return ticket;
      },
      py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
      py::arg("depth_scale"), py::arg("pose") = py::none(), py::arg("max_range_m") = -1.0,
      py::arg("discretize") = false, py::kw_only(), py::arg("colors") = py::none(),
      py::arg("color_fold") = "average", py::arg("max_range") = py::none(),
      "insert_depth_image(depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, discretize, "
      "colors, color_fold, max_range) without waiting (pixels and colours are copied before "
      "it returns). Returns the scan's ticket.");

  cls.def(
      "colors",
      [](PyColorMap& self, py::handle points, bool copy) {
        const ArrayView pts(points, "points", Layout::kPoints, {DType::kFloat32},
                            copyArgument(copy));
        noteInput(pts.data());
        const std::vector<Rgb> found =
            self.runAs<ColorMap>([&](ColorMap& map) { return map.colors(pts.points()); });
        std::vector<std::uint8_t> bytes(3 * found.size());
        for (std::size_t i = 0; i < found.size(); ++i) {
          bytes[3 * i] = found[i].r;
          bytes[3 * i + 1] = found[i].g;
          bytes[3 * i + 2] = found[i].b;
        }
        return likeInput(points, ownedArray(std::move(bytes), withExtent(pts.leading(), 3)));
      },
      py::arg("points"), py::kw_only(), py::arg("copy") = false,
      "The colour of the node search() finds for each of points (float32 (N, 3), (H, W, 3) or "
      "(N, 4) as in search), on the device: uint8 (N, 3) r, g, b ((H, W, 3) for an organised "
      "cloud), white (255, 255, 255) where search finds no node or the node has no colour yet; "
      "a torch tensor when points is one. copy: as in search.");
  cls.def("__repr__", [](const PyColorMap& self) {
    return "ColorMap(resolution=" + std::to_string(self.map().params().resolution) + ")";
  });
}

void bindStampedMap(py::module_& m) {
  py::class_<PyStampedMap, Map> cls(m, "StampedMap", kStampedMapDoc);
  defInit<PyStampedMap, StampedMap>(cls, "An empty stamped map (OcTreeStamped).");
  defRead(cls, Payload::kStamp,
          "A new StampedMap from an OctoMap OcTreeStamped .ot file; FormatError for another tree "
          "type (Map.read reads every type). context and max_device_bytes as in Map.read.");

  constexpr const char* kStampDoc =
      " stamp: the scan's time in whole seconds, an int from 0 to 2**32 - 1, which every leaf "
      "the scan updates takes (OcTreeStamped's time(NULL)); None: the clock's now "
      "(int(time.time())).";
  cls.def(
      "insert_point_cloud",
      [](PyStampedMap& self, py::handle points, py::handle origin, py::handle pose,
         double max_range_m, bool discretize, py::handle stamp, bool copy, py::handle max_range) {
        PointScan scan(points, origin, pose, max_range_m, discretize, copy, max_range);
        scan.stamp(stamp);
        noteInput(scan.data());
        return self.run([&](OccupancyMap& map) { return scan.insert(map); });
      },
      py::arg("points"), py::arg("origin"), py::arg("pose") = py::none(),
      py::arg("max_range_m") = -1.0, py::arg("discretize") = false, py::kw_only(),
      py::arg("stamp") = py::none(), py::arg("copy") = false, py::arg("max_range") = py::none(),
      (std::string("Map.insert_point_cloud (points, origin, pose, max_range_m, discretize, "
                   "copy, max_range as there) at time stamp.") +
       kStampDoc + " Returns ScanStats.")
          .c_str());
  cls.def(
      "submit_point_cloud",
      [](PyStampedMap& self, py::handle points, py::handle origin, py::handle pose,
         double max_range_m, bool discretize, py::handle stamp, bool copy, py::handle max_range) {
        PointScan scan(points, origin, pose, max_range_m, discretize, copy, max_range);
        scan.stamp(stamp);
        noteInput(scan.data());
        const ScanTicket ticket = self.run([&](OccupancyMap& map) { return scan.submit(map); });
        self.noteTicket(ticket);
        return ticket;
      },
      py::arg("points"), py::arg("origin"), py::arg("pose") = py::none(),
      py::arg("max_range_m") = -1.0, py::arg("discretize") = false, py::kw_only(),
      py::arg("stamp") = py::none(), py::arg("copy") = false, py::arg("max_range") = py::none(),
      (std::string("insert_point_cloud(points, origin, pose, max_range_m, discretize, stamp, "
                   "copy, max_range) without waiting. Returns the scan's ticket.") +
       kStampDoc)
          .c_str());
  cls.def(
      "insert_depth_image",
      [](PyStampedMap& self, py::handle depth, float fx, float fy, float cx, float cy,
         float depth_scale, py::handle pose, double max_range_m, bool discretize, py::handle stamp,
         py::handle max_range) {
        DepthScan scan(depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, discretize,
                       max_range);
        scan.stamp(stamp);
        noteInput(scan.data());
        return self.run([&](OccupancyMap& map) { return scan.insert(map); });
      },
      py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
      py::arg("depth_scale"), py::arg("pose") = py::none(), py::arg("max_range_m") = -1.0,
      py::arg("discretize") = false, py::kw_only(), py::arg("stamp") = py::none(),
      py::arg("max_range") = py::none(),
      (std::string("Map.insert_depth_image (depth, fx, fy, cx, cy, depth_scale, pose, "
                   "max_range_m, discretize, max_range as there) at time stamp.") +
       kStampDoc + " Returns ScanStats.")
          .c_str());
  cls.def(
      "submit_depth_image",
      [](PyStampedMap& self, py::handle depth, float fx, float fy, float cx, float cy,
         float depth_scale, py::handle pose, double max_range_m, bool discretize, py::handle stamp,
         py::handle max_range) {
        DepthScan scan(depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, discretize,
                       max_range);
        scan.stamp(stamp);
        noteInput(scan.data());
        const ScanTicket ticket = self.run([&](OccupancyMap& map) { return scan.submit(map); });
        self.noteTicket(ticket);
        return ticket;
      },
      py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
      py::arg("depth_scale"), py::arg("pose") = py::none(), py::arg("max_range_m") = -1.0,
      py::arg("discretize") = false, py::kw_only(), py::arg("stamp") = py::none(),
      py::arg("max_range") = py::none(),
      (std::string("insert_depth_image(depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, "
                   "discretize, stamp, max_range) without waiting. Returns the scan's ticket.") +
       kStampDoc)
          .c_str());

  cls.def(
      "degrade_outdated",
      [](PyStampedMap& self, py::handle threshold_s, py::handle now) {
        const std::uint32_t threshold = secondsOf(threshold_s, "threshold_s");
        const std::uint32_t at = secondsOf(now, "now");
        self.runAs<StampedMap>([&](StampedMap& map) { map.degradeOutdated(at, threshold); });
      },
      py::arg("threshold_s"), py::arg("now") = py::none(),
      "OcTreeStamped::degradeOutdatedNodes(threshold_s) at time now, on the device: every "
      "occupied leaf (pruned leaves included) with now - stamp > threshold_s (seconds, "
      "unsigned as OctoMap) takes one miss and keeps its stamp; then the inner nodes are "
      "updated (their stamps become now). threshold_s, now: ints from 0 to 2**32 - 1; now None: "
      "the clock's now (int(time.time())), as OctoMap.");
  cls.def(
      "stamps",
      [](PyStampedMap& self, py::handle points, bool copy) {
        const ArrayView pts(points, "points", Layout::kPoints, {DType::kFloat32},
                            copyArgument(copy));
        noteInput(pts.data());
        std::vector<std::uint32_t> found =
            self.runAs<StampedMap>([&](StampedMap& map) { return map.stamps(pts.points()); });
        py::object out = ownedArray(std::move(found), pts.leading());
        if (!isTorch(points)) return out;
        // torch (before 2.3) has no uint32: the stamps as int64, which holds every one.
        return py::module_::import("torch").attr("from_numpy")(out.attr("astype")("int64"));
      },
      py::arg("points"), py::kw_only(), py::arg("copy") = false,
      "The time stamp (whole seconds) of the node search() finds for each of points (float32 "
      "(N, 3), (H, W, 3) or (N, 4) as in search), on the device: uint32 (N,) ((H, W) for an "
      "organised cloud; an int64 torch tensor when points is one), 0 where search finds no node. "
      "copy: as in search.");
  cls.def(
      "last_update_time",
      [](PyStampedMap& self) {
        return self.runAs<StampedMap>([](StampedMap& map) { return map.lastUpdateTime(); });
      },
      "OcTreeStamped::getLastUpdateTime: the root's stamp, in seconds (0 for an empty map).");
  cls.def("__repr__", [](const PyStampedMap& self) {
    return "StampedMap(resolution=" + std::to_string(self.map().params().resolution) + ")";
  });
}

}  // namespace

// The boxes in metres of tiles: one row min x, y, z, max x, y, z per tile.
py::array_t<double> tileBoxes(const std::vector<StoreFollower::TileBox>& tiles, double resolution) {
  const auto n = static_cast<py::ssize_t>(tiles.size());
  py::array_t<double> boxes({n, py::ssize_t{6}});
  auto out = boxes.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const StoreFollower::TileBox& t = tiles[static_cast<std::size_t>(i)];
    const double side = resolution * static_cast<double>(1u << (16 - t.depth));
    for (int a = 0; a < 3; ++a) {
      const double lo = (static_cast<double>(t.min_key[a]) - 32768.0) * resolution;
      out(i, a) = lo;
      out(i, a + 3) = lo + side;
    }
  }
  return boxes;
}

py::dict updateDict(const StoreFollower::Update& u, double resolution) {
  py::dict d;
  d["seq"] = u.seq;
  d["changed"] = tileBoxes(u.changed, resolution);
  d["dropped"] = tileBoxes(u.dropped, resolution);
  d["bytes_read"] = u.bytes_read;
  return d;
}

void bindStoredMap(py::module_& m) {
  py::class_<PyStoredMap> cls(
      m, "StoredMap",
      "A map of a store (an SQLite file or a PostgreSQL URI) that scans are inserted into, each "
      "committed with a log row naming its source and scan index, as 'octovk integrate --store' "
      "commits: each scan first takes the map's write lock and loads what other writers "
      "committed, so several processes may write one map. A map is an OcTree, a ColorOcTree "
      "(scans with colors) or an OcTreeStamped (scans with a stamp), as made. snapshot() gives "
      "the committed map as a Map, ColorMap or StampedMap for queries.");
  cls.def_static(
      "open",
      [](py::handle store, const std::string& name, std::optional<double> resolution,
         double prob_hit, double prob_miss, double clamping_min, double clamping_max,
         double occupancy_threshold, const std::string& tree_type, py::object context,
         std::size_t max_device_bytes) {
        const std::string location = pathString(store, "store");
        context = orDefault(std::move(context));
        Context& ctx = contextOf(context);
        std::optional<Payload> payload;
        for (const Payload p : {Payload::kNone, Payload::kColor, Payload::kStamp})
          if (tree_type == treeTypeName(p)) payload = p;
        if (!payload)
          throw Error(ErrorCode::kInvalidArgument,
                      "StoredMap.open: tree_type '" + tree_type +
                          "' is none of 'OcTree', 'ColorOcTree', 'OcTreeStamped'");
        std::optional<MapParams> create;
        if (resolution) {
          create = sensorParams(*resolution, prob_hit, prob_miss, clamping_min, clamping_max,
                                occupancy_threshold);
          create->max_device_bytes = max_device_bytes;
          create->payload = *payload;
        }
        std::optional<StoredMap> opened;
        {
          py::gil_scoped_release release;
          opened.emplace(StoredMap::open(ctx, location, name, create));
        }
        return std::make_unique<PyStoredMap>(context, std::move(*opened));
      },
      py::arg("store"), py::arg("map") = "default", py::kw_only(),
      py::arg("resolution") = py::none(), py::arg("prob_hit") = 0.7, py::arg("prob_miss") = 0.4,
      py::arg("clamping_min") = 0.1192, py::arg("clamping_max") = 0.971,
      py::arg("occupancy_threshold") = 0.5, py::arg("tree_type") = "OcTree",
      py::arg("context") = py::none(), py::arg("max_device_bytes") = 0,
      "Opens map `map` of the store as its last committed scan left it. With resolution (and "
      "prob_hit, prob_miss, clamping_min, clamping_max, occupancy_threshold, tree_type: "
      "'OcTree', 'ColorOcTree' or 'OcTreeStamped') a missing map, and a missing SQLite file, is "
      "created; a map that exists keeps its own parameters and tree type. Without "
      "resolution a missing map raises InvalidArgumentError. context: a Context (None: "
      "default_context()); max_device_bytes caps the device map.");
  cls.def(
      "insert_point_cloud",
      [](PyStoredMap& self, py::handle points, py::handle origin, py::handle pose,
         double max_range_m, bool discretize, py::handle colors, const std::string& color_fold,
         py::handle stamp, const std::string& source, std::optional<std::uint64_t> scan,
         bool copy) {
        PointScan cloud(points, origin, pose, max_range_m, discretize, copy, py::none());
        if (!colors.is_none()) cloud.colors(colors, color_fold);
        if (!stamp.is_none()) cloud.stamp(stamp);
        noteInput(cloud.data());
        const std::uint64_t index = scan ? *scan : self.nextScan();
        return self.run([&](StoredMap& stored) {
          return stored.insert([&](OccupancyMap& map) { return cloud.insert(map); }, source, index);
        });
      },
      py::arg("points"), py::arg("origin"), py::arg("pose") = py::none(),
      py::arg("max_range_m") = -1.0, py::arg("discretize") = false, py::kw_only(),
      py::arg("colors") = py::none(), py::arg("color_fold") = "average",
      py::arg("stamp") = py::none(), py::arg("source") = "python", py::arg("scan") = py::none(),
      py::arg("copy") = false,
      "Map.insert_point_cloud (points, origin, pose, max_range_m, discretize, copy as there; "
      "colors and color_fold for a ColorOcTree map and stamp for an OcTreeStamped one, as "
      "ColorMap's and StampedMap's), then the scan committed: its changed tiles and a log row "
      "naming source and scan (None: the scans this object committed so far), which 'octovk store "
      "log' prints. Returns "
      "ScanStats.");
  cls.def(
      "snapshot",
      [](PyStoredMap& self, std::size_t max_device_bytes) {
        Context& ctx = contextOf(self.context());
        auto made = self.run([&](StoredMap& stored) {
          MapParams params = stored.map().params();
          params.max_device_bytes = max_device_bytes;
          OccupancyMap copy(ctx, params);
          copy.upload(stored.map().download());
          return copy;
        });
        return asMapClass(self.context(), std::move(made));
      },
      py::kw_only(), py::arg("max_device_bytes") = 0,
      "The committed map as a new Map (ColorMap, StampedMap: its tree type) on the same Context (a "
      "copy: later scans do not reach "
      "it), capped at max_device_bytes (0: no cap).");
  cls.def_property_readonly(
      "last_seq",
      [](PyStoredMap& self) { return self.run([](StoredMap& s) { return s.lastSeq(); }); },
      "the sequence number of the last scan this object committed or loaded");
  cls.def_property_readonly(
      "name", [](PyStoredMap& self) { return self.run([](StoredMap& s) { return s.name(); }); });
  cls.def_property_readonly("resolution", [](PyStoredMap& self) {
    return self.run([](StoredMap& s) { return s.map().params().resolution; });
  });
  cls.def_property_readonly(
      "tree_type",
      [](PyStoredMap& self) {
        return self.run(
            [](StoredMap& s) { return std::string(treeTypeName(s.map().params().payload)); });
      },
      "'OcTree', 'ColorOcTree' or 'OcTreeStamped': what the map's nodes hold");
}

void bindStoreFollower(py::module_& m) {
  py::class_<StoreFollower> cls(
      m, "StoreFollower",
      "A map of a store (an SQLite file or a PostgreSQL URI, as 'octovk integrate --store' "
      "writes it) followed while writers commit scans: each poll reads, in one snapshot, the "
      "keys of the map's tiles and the bodies of only the tiles written since the last poll. "
      "No device needed; map() gives the followed state as a Map.");
  cls.def(py::init([](py::handle store, const std::string& name) {
            const std::string location = pathString(store, "store");
            py::gil_scoped_release release;
            return std::make_unique<StoreFollower>(location, name);
          }),
          py::arg("store"), py::arg("map") = "default",
          "Opens map `map` of the store; InvalidArgumentError when the store holds no such map.");
  cls.def(
      "poll",
      [](StoreFollower& self) -> py::object {
        std::optional<StoreFollower::Update> u;
        {
          py::gil_scoped_release release;
          u = self.poll();
        }
        if (!u) return py::none();
        return updateDict(*u, self.params().resolution);
      },
      "What was committed since the last poll, or None when nothing was (the first poll reads "
      "every tile): a dict with 'seq' (the last committed scan's sequence number), 'changed' "
      "and 'dropped' (float64 (N, 6): per tile min x, y, z, max x, y, z in metres; dropped "
      "tiles were merged into larger leaves by pruning) and 'bytes_read'.");
  cls.def(
      "updates",
      [](py::object self, double interval_s, std::optional<std::uint64_t> until_seq) {
        (void)self.cast<StoreFollower&>();  // refuses a StoreFollower whose __init__ never ran
        if (!(interval_s >= 0.001 && interval_s <= 3600))
          throw Error(ErrorCode::kInvalidArgument,
                      "updates: interval_s " + std::to_string(interval_s) +
                          " is not a number of seconds from 0.001 to 3600");
        return FollowIterator{std::move(self), interval_s, until_seq};
      },
      py::arg("interval_s") = 0.5, py::arg("until_seq") = py::none(),
      "An iterator of poll()'s updates: it looks at the store every interval_s seconds and "
      "yields each update, forever or until the map's committed scans reach until_seq. "
      "Ctrl-C (KeyboardInterrupt) ends a wait.");
  cls.def(
      "map",
      [](StoreFollower& self, py::object context, std::size_t max_device_bytes) {
        context = orDefault(std::move(context));
        Context& ctx = contextOf(context);
        MapParams params = self.params();
        params.max_device_bytes = max_device_bytes;
        std::optional<OccupancyMap> made;
        {
          py::gil_scoped_release release;
          made.emplace(ctx, params);
          if (self.tree().root_exists) made->upload(self.tree());
        }
        return asMapClass(std::move(context), std::move(*made));
      },
      py::kw_only(), py::arg("context") = py::none(), py::arg("max_device_bytes") = 0,
      "The map as of the last poll, as a new Map (ColorMap, StampedMap: its tree type) with the "
      "store's resolution and sensor model, on context (None: default_context()), capped at "
      "max_device_bytes (0: no cap).");
  cls.def_property_readonly("seq", &StoreFollower::seq,
                            "the sequence number of the last poll (0: none yet)");
  cls.def_property_readonly("resolution",
                            [](const StoreFollower& self) { return self.params().resolution; });
  cls.def_property_readonly(
      "tree_type",
      [](const StoreFollower& self) { return std::string(treeTypeName(self.params().payload)); },
      "'OcTree', 'ColorOcTree' or 'OcTreeStamped': what the map's nodes hold");
  cls.def_property_readonly("tile_depth", &StoreFollower::tileDepth,
                            "the depth of OctoMap's 16 at which the map is cut into tiles");

  py::class_<FollowIterator>(m, "_StoreUpdates",
                             "StoreFollower.updates()'s iterator of the store's updates.")
      .def("__iter__",
           [](py::object self) {
             (void)self.cast<FollowIterator&>();  // refuses one whose __init__ never ran
             return self;
           })
      .def("__next__", [](FollowIterator& it) -> py::object {
        auto& follower = it.follower.cast<StoreFollower&>();
        for (;;) {
          if (it.until_seq && follower.seq() >= *it.until_seq) throw py::stop_iteration();
          std::optional<StoreFollower::Update> u;
          {
            py::gil_scoped_release release;
            u = follower.poll();
          }
          if (u) return updateDict(*u, follower.params().resolution);
          // Wait in short steps, so that Ctrl-C is seen during a long interval; a PostgreSQL
          // store ends the wait at a commit.
          double left = it.interval_s;
          while (left > 0) {
            const double step = std::min(left, 0.05);
            bool committed = false;
            {
              py::gil_scoped_release release;
              committed = follower.wait(step);
            }
            if (PyErr_CheckSignals() != 0) throw py::error_already_set();
            if (committed) break;
            left -= step;
          }
        }
      });
}

void bindMap(py::module_& m) {
  py::class_<OccupancyMap::DeviceBytes>(m, "DeviceBytes", "Device bytes a map holds, by use.")
      .def_readonly("pool", &OccupancyMap::DeviceBytes::pool,
                    "nodes, block records, free-block stack")
      .def_readonly("leaf_boxes", &OccupancyMap::DeviceBytes::leaf_boxes)
      .def_readonly("scratch", &OccupancyMap::DeviceBytes::scratch,
                    "per-scan buffers, sized by the largest scan since trim()")
      .def_readonly("queries", &OccupancyMap::DeviceBytes::queries,
                    "query input and output, castRay's acceleration structure")
      .def_readonly("changes", &OccupancyMap::DeviceBytes::changes,
                    "the change set (change detection)")
      .def_readonly("distance_fields", &OccupancyMap::DeviceBytes::distance_fields,
                    "the distance fields built on the map")
      .def_property_readonly("total", &OccupancyMap::DeviceBytes::total)
      .def("__repr__", [](const OccupancyMap::DeviceBytes& b) {
        return "DeviceBytes(pool=" + std::to_string(b.pool) +
               ", leaf_boxes=" + std::to_string(b.leaf_boxes) +
               ", scratch=" + std::to_string(b.scratch) + ", queries=" + std::to_string(b.queries) +
               ", changes=" + std::to_string(b.changes) +
               ", distance_fields=" + std::to_string(b.distance_fields) + ")";
      });

  using CastRayInfo = OccupancyMap::CastRayInfo;
  py::class_<CastRayInfo>(m, "CastRayInfo",
                          "castRay's backend on a map and what its acceleration structure cost.")
      .def_readonly("backend", &CastRayInfo::backend,
                    "WALK, RAY_QUERY or RT_PIPELINE, as cast_rays runs")
      .def_readonly("builds", &CastRayInfo::builds, "acceleration-structure builds since trim()")
      .def_readonly("last_build_ms", &CastRayInfo::last_build_ms)
      .def_readonly("occupied_boxes", &CastRayInfo::occupied_boxes)
      .def_readonly("device_bytes", &CastRayInfo::device_bytes)
      .def_readonly("cap_fallbacks", &CastRayInfo::cap_fallbacks,
                    "cast_rays calls answered by the walk because of max_device_bytes");

  py::class_<Map> map(m, "Map", kMapDoc);
  defInit<Map, OccupancyMap>(map, "An empty map.");
  defRead(map, std::nullopt,
          "A new map from an OctoMap .bt or .ot file (the file's resolution and, for .ot, its "
          "sensor model), of the class its tree type names: Map (OcTree), ColorMap (ColorOcTree) "
          "or StampedMap (OcTreeStamped). Raises FormatError naming the file and the fault, "
          "IoError, or OutOfDeviceMemoryError when it does not fit under max_device_bytes.");

  map.def_static(
      "open",
      [](py::handle store, const std::string& name, py::object context,
         std::size_t max_device_bytes) {
        // A PostgreSQL URI is a str; an SQLite file may be a str or a path-like.
        const std::string location = pathString(store, "store");
        context = orDefault(std::move(context));
        Context& ctx = contextOf(context);
        std::optional<OccupancyMap> made;
        {
          py::gil_scoped_release release;
          made.emplace(readStoredMap(ctx, location, name, max_device_bytes));
        }
        return asMapClass(std::move(context), std::move(*made));
      },
      py::arg("store"), py::arg("map") = "default", py::kw_only(), py::arg("context") = py::none(),
      py::arg("max_device_bytes") = 0,
      "A new map from a store (an SQLite file or a PostgreSQL URI postgresql://..., as "
      "'octovk integrate --store' writes it): map `map` as its last committed scan left it, with "
      "the store's resolution and sensor model, as the class of its tree type (Map, ColorMap or "
      "StampedMap). A snapshot: scans inserted into it stay in this "
      "Map, and later commits to the store do not reach it. Raises InvalidArgumentError when "
      "the store holds no such map, IoError when it cannot be read, FormatError for a damaged "
      "tile, OutOfDeviceMemoryError over max_device_bytes.");

  map.def(
      "write",
      [](Map& self, py::handle path) {
        const std::string file = pathString(path, "path");
        self.run([&](OccupancyMap& map) { writeMapFile(map, file); });
      },
      py::arg("path"),
      "Writes the map to path as its extension says: .bt (OctoMap's writeBinary: max-likelihood, "
      "pruned) or .ot (full log-odds). Written to a temporary file and renamed: a failed "
      "write leaves no partial file.");

  map.def(
      "insert_point_cloud",
      [](Map& self, py::handle points, py::handle origin, py::handle pose, double max_range_m,
         bool discretize, bool copy, py::handle max_range) {
        const PointScan scan(points, origin, pose, max_range_m, discretize, copy, max_range);
        noteInput(scan.data());
        return self.run([&](OccupancyMap& map) { return scan.insert(map); });
      },
      py::arg("points"), py::arg("origin"), py::arg("pose") = py::none(),
      py::arg("max_range_m") = -1.0, py::arg("discretize") = false, py::kw_only(),
      py::arg("copy") = false, py::arg("max_range") = py::none(),
      "OctoMap's insertPointCloud(points, origin, max_range, lazy_eval=False, discretize): "
      "points and origin in the world frame; with `pose` (T_world_sensor) both are in the "
      "sensor frame and moved to the world on the device. points: float32 (N, 3), an organised "
      "cloud (H, W, 3), or (N, 4) with x, y, z first (x, y, z, intensity: its first three "
      "columns). max_range_m: rays are cut at this many metres (< 0: none). copy: True copies "
      "points that cannot be read in place ((N, 4) points, a strided view such as P4[:, :3]); "
      "False refuses them. max_range: the deprecated name of max_range_m. Returns ScanStats. "
      "Waits until the scan is in the map.");

  map.def(
      "submit_point_cloud",
      [](Map& self, py::handle points, py::handle origin, py::handle pose, double max_range_m,
         bool discretize, bool copy, py::handle max_range) {
        const PointScan scan(points, origin, pose, max_range_m, discretize, copy, max_range);
        noteInput(scan.data());
        const ScanTicket ticket = self.run([&](OccupancyMap& map) { return scan.submit(map); });
        self.noteTicket(ticket);
        return ticket;
      },
      py::arg("points"), py::arg("origin"), py::arg("pose") = py::none(),
      py::arg("max_range_m") = -1.0, py::arg("discretize") = false, py::kw_only(),
      py::arg("copy") = false, py::arg("max_range") = py::none(),
      "insert_point_cloud(points, origin, pose, max_range_m, discretize, copy, max_range) "
      "without waiting for "
      "the device: the points are copied before it returns (the array may be reused at once). "
      "Returns the scan's ticket (int). Errors the device finds are raised by the next flush() "
      "or query, naming the scan (Error.scan).");

  map.def(
      "insert_depth_image",
      [](Map& self, py::handle depth, float fx, float fy, float cx, float cy, float depth_scale,
         py::handle pose, double max_range_m, bool discretize, py::handle max_range) {
        const DepthScan scan(depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, discretize,
                             max_range);
        noteInput(scan.data());
        return self.run([&](OccupancyMap& map) { return scan.insert(map); });
      },
      py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
      py::arg("depth_scale"), py::arg("pose") = py::none(), py::arg("max_range_m") = -1.0,
      py::arg("discretize") = false, py::kw_only(), py::arg("max_range") = py::none(),
      "A depth image (float32 or uint16, (H, W) or (1, H, W), row by row), unprojected on the "
      "device with "
      "the pinhole camera fx, fy, cx, cy (pixels) and depth_scale (depth units per metre: TUM "
      "5000, metres in float 1), then inserted from the camera centre with pose "
      "T_world_camera (camera frame x right, y down, z forward). Pixels with depth 0 or "
      "non-finite are skipped. max_range_m, discretize and max_range as in insert_point_cloud. "
      "Returns ScanStats.");

  map.def(
      "submit_depth_image",
      [](Map& self, py::handle depth, float fx, float fy, float cx, float cy, float depth_scale,
         py::handle pose, double max_range_m, bool discretize, py::handle max_range) {
        const DepthScan scan(depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, discretize,
                             max_range);
        noteInput(scan.data());
        const ScanTicket ticket = self.run([&](OccupancyMap& map) { return scan.submit(map); });
        self.noteTicket(ticket);
        return ticket;
      },
      py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
      py::arg("depth_scale"), py::arg("pose") = py::none(), py::arg("max_range_m") = -1.0,
      py::arg("discretize") = false, py::kw_only(), py::arg("max_range") = py::none(),
      "insert_depth_image(depth, fx, fy, cx, cy, depth_scale, pose, max_range_m, discretize, "
      "max_range) "
      "without waiting (the pixels are copied before it returns). Returns "
      "the scan's ticket.");

  map.def("flush", &Map::flush,
          "Waits until every submitted scan is in the map; raises the error of a scan the "
          "device refused (Error.scan names it; the scans before it stay in the map). Ctrl-C "
          "interrupts the wait (KeyboardInterrupt) and leaves the scans in flight: the next "
          "flush() or query completes them.");
  map.def(
      "finished",
      [](Map& self, ScanTicket ticket) {
        return self.run([&](OccupancyMap& map) { return map.finished(ticket); });
      },
      py::arg("ticket"), "Whether submitted scan `ticket` is in the map (does not wait).");
  map.def(
      "take_scan_stats",
      [](Map& self) { return self.run([](OccupancyMap& map) { return map.takeScanStats(); }); },
      "ScanStats of the submitted scans known to be in the map since the last call, in "
      "ticket order (does not wait).");
  map.def_property_readonly(
      "scans_in_flight",
      [](Map& self) { return self.run([](OccupancyMap& map) { return map.scansInFlight(); }); },
      "Submitted scans not yet known to be in the map (a property: it does not wait).");

  map.def(
      "search",
      [](Map& self, py::handle points, py::handle out, bool copy) {
        const ArrayView pts(points, "points", Layout::kPoints, {DType::kFloat32},
                            copyArgument(copy));
        const std::vector<py::ssize_t> lead = pts.leading();
        const py::tuple outs = outTuple(out, 3,
                                        "(state uint8 (N,), log_odds float32 (N,), "
                                        "depth uint8 (N,))");
        std::optional<ArrayView> state_v, log_odds_v, depth_v;
        py::object state =
            resultColumn<std::uint8_t>(outs[0], "out[0] (state)", DType::kUint8, lead, state_v);
        py::object log_odds =
            resultColumn<float>(outs[1], "out[1] (log_odds)", DType::kFloat32, lead, log_odds_v);
        py::object depth =
            resultColumn<std::uint8_t>(outs[2], "out[2] (depth)", DType::kUint8, lead, depth_v);
        noteInput(pts.data());
        auto* s = static_cast<std::uint8_t*>(state_v->data());
        auto* l = static_cast<float*>(log_odds_v->data());
        auto* d = static_cast<std::uint8_t*>(depth_v->data());
        self.run([&](OccupancyMap& map) {
          const std::vector<Lookup> found = map.search(pts.points());
          for (std::size_t i = 0; i < found.size(); ++i) {
            s[i] = static_cast<std::uint8_t>(found[i].state);
            l[i] = found[i].log_odds;
            d[i] = static_cast<std::uint8_t>(found[i].depth);
          }
        });
        return queryResults(points, !out.is_none(), {state, log_odds, depth});
      },
      py::arg("points"), py::arg("out") = py::none(), py::kw_only(), py::arg("copy") = false,
      "OctoMap's search() for each of points (float32 (N, 3), (H, W, 3) or (N, 4) as in "
      "insert_point_cloud), on the device: the deepest existing node on the point's path. "
      "Returns (state, log_odds, depth), each with one entry per point ((N,), or (H, W) for an "
      "organised cloud): state uint8 (CellState: 0 unknown, 1 free, 2 occupied), log_odds "
      "float32 (0 when unknown), depth uint8 (16 = finest, 0 when unknown); torch tensors "
      "(sharing the arrays' memory) when points is one. out: a tuple of three such arrays to "
      "write into (returned). copy: as in insert_point_cloud.");

  map.def(
      "cast_rays",
      [](Map& self, py::handle origins, py::handle directions, double max_range_m,
         bool ignore_unknown, py::handle out, bool copy, py::handle max_range) {
        const double range = rangeOf(max_range_m, max_range);
        const ArrayView dirs(directions, "directions", Layout::kPoints, {DType::kFloat32},
                             copyArgument(copy));
        const std::size_t n = dirs.extent(0);
        const std::vector<py::ssize_t> lead = dirs.leading();
        std::optional<ArrayView> origin_v;
        Eigen::Vector3f one_origin = Eigen::Vector3f::Zero();
        if (isPointArray(origins)) {
          origin_v.emplace(origins, "origins", Layout::kPoints,
                           std::initializer_list<DType>{DType::kFloat32}, copyArgument(copy));
          if (origin_v->leading() != lead)
            throw py::value_error(
                "origins: expected one origin per direction, of shape " +
                std::string(py::str(py::tuple(py::cast(withExtent(lead, 3))))) +
                ", or 3 numbers for every ray; got shape " +
                std::string(py::str(py::tuple(py::cast(withExtent(origin_v->leading(), 3))))));
        } else {
          one_origin = toVector3(origins, "origins");
        }
        const py::tuple outs = outTuple(out, 2, "(hit uint8 (N,), end float32 (N, 3))");
        std::optional<ArrayView> hit_v, end_v;
        py::object hit =
            resultColumn<std::uint8_t>(outs[0], "out[0] (hit)", DType::kUint8, lead, hit_v);
        py::object end = resultColumn<float>(outs[1], "out[1] (end)", DType::kFloat32,
                                             withExtent(lead, 3), end_v);
        auto* h = static_cast<std::uint8_t*>(hit_v->data());
        auto* e = static_cast<float*>(end_v->data());
        self.run([&](OccupancyMap& map) {
          std::vector<Ray> rays(n);
          const auto* dir = static_cast<const Eigen::Vector3f*>(dirs.data());
          const auto* org =
              origin_v ? static_cast<const Eigen::Vector3f*>(origin_v->data()) : nullptr;
          for (std::size_t i = 0; i < rays.size(); ++i) {
            rays[i].origin = org ? org[i] : one_origin;
            rays[i].direction = dir[i];
            rays[i].max_range_m = range;
            rays[i].ignore_unknown = ignore_unknown;
          }
          const std::vector<RayHit> hits = map.castRays(rays);
          for (std::size_t i = 0; i < hits.size(); ++i) {
            h[i] = hits[i].hit ? 1 : 0;
            for (int k = 0; k < 3; ++k) e[3 * i + static_cast<std::size_t>(k)] = hits[i].end[k];
          }
        });
        return queryResults(directions, !out.is_none(), {hit, end});
      },
      py::arg("origins"), py::arg("directions"), py::arg("max_range_m") = -1.0,
      py::arg("ignore_unknown") = false, py::arg("out") = py::none(), py::kw_only(),
      py::arg("copy") = false, py::arg("max_range") = py::none(),
      "OctoMap's castRay(origin, direction, end, ignore_unknown, max_range) for each ray, on "
      "the device. directions: float32 (N, 3) (or (H, W, 3), (N, 4) as points in "
      "insert_point_cloud), need not be normalised; origins: one per direction, of the same "
      "shape, or 3 numbers for every ray; max_range_m: metres (<= 0: to the map's border); "
      "ignore_unknown: unknown cells count as free. Returns (hit, end): hit uint8 (N,) (1: an "
      "occupied cell was hit), end float32 (N, 3) (the centre of the last cell visited; the "
      "origin where OctoMap leaves it untouched), (H, W) and (H, W, 3) for organised "
      "directions; torch tensors when directions is one. out: a tuple of two such arrays. "
      "copy: as in insert_point_cloud, for origins and directions. max_range: the deprecated "
      "name of max_range_m.");

  map.def(
      "leaves_in_box",
      [](Map& self, py::handle min, py::handle max, bool occupied_only) {
        const Eigen::Vector3f lo = toVector3(min, "min");
        const Eigen::Vector3f hi = toVector3(max, "max");
        return leafArrays(
            self.run([&](OccupancyMap& map) { return map.leavesInBox(lo, hi, occupied_only); }));
      },
      py::arg("min"), py::arg("max"), py::arg("occupied_only") = false,
      "The leaves OctoMap's leaf_bbx_iterator(min, max) visits (only the occupied ones with "
      "occupied_only), found on the device: (centers float32 (N, 3), sizes float32 (N,), "
      "log_odds float32 (N,)), views of one buffer. Empty if a corner lies outside the map.");
  map.def(
      "leaves",
      [](Map& self) {
        return leafArrays(self.run([](OccupancyMap& map) { return map.downloadLeafBoxes(); }));
      },
      "Every leaf of the map: (centers float32 (N, 3), sizes float32 (N,), log_odds float32 "
      "(N,)).");

  map.def(
      "clear_box",
      [](Map& self, py::handle min, py::handle max) {
        const Eigen::Vector3f lo = toVector3(min, "min");
        const Eigen::Vector3f hi = toVector3(max, "max");
        self.run([&](OccupancyMap& map) { map.clearBox(lo, hi); });
      },
      py::arg("min"), py::arg("max"),
      "octomap_server's clear_bbx on the device: every leaf OctoMap's leaf_bbx_iterator(min, max) "
      "visits gets the lower clamping bound's log-odds, then the inner nodes are updated as "
      "updateInnerOccupancy does. min, max: the box's corners, 3 numbers each, min <= max.");
  map.def(
      "keep_box",
      [](Map& self, py::handle min, py::handle max) {
        const Eigen::Vector3f lo = toVector3(min, "min");
        const Eigen::Vector3f hi = toVector3(max, "max");
        self.run([&](OccupancyMap& map) { map.keepBox(lo, hi); });
      },
      py::arg("min"), py::arg("max"),
      "Keeps only a box (a rolling window), on the device: the leaves OctoMap's "
      "leaf_bbx_iterator(min, max) visits (a pruned leaf reaching into the box stays whole) and "
      "the inner nodes above them, each the maximum of its children; every other node is "
      "deleted and its memory reused by later scans. A corner outside the map keeps nothing. "
      "min, max: the box's corners, 3 numbers each, min <= max.");
  map.def(
      "compact", [](Map& self) { self.run([&](OccupancyMap& map) { map.compact(); }); },
      "Gives the node pool's free blocks back to the device (after keep_box, say): the tree is "
      "moved into a pool sized for it, through the host; for an occasional call.");
  map.def(
      "enable_change_detection",
      [](Map& self, bool enable) {
        self.run([&](OccupancyMap& map) { map.enableChangeDetection(enable); });
      },
      py::arg("enable"),
      "OcTree::enableChangeDetection. enable: True turns it on for the scans inserted or "
      "submitted after this call, which then note every leaf they update as OctoMap does "
      "(created: True; occupancy flipped: False; flipped back: removed); False turns it off and "
      "keeps the keys noted so far. The set lives on the device.");
  map.def(
      "is_change_detection_enabled",
      [](Map& self) {
        return self.run([](OccupancyMap& map) { return map.isChangeDetectionEnabled(); });
      },
      "Whether change detection is on (OcTree::isChangeDetectionEnabled).");
  map.def(
      "reset_change_detection",
      [](Map& self) { self.run([](OccupancyMap& map) { map.resetChangeDetection(); }); },
      "Empties the change set (OcTree::resetChangeDetection).");
  map.def(
      "num_changes_detected",
      [](Map& self) {
        return self.run([](OccupancyMap& map) { return map.numChangesDetected(); });
      },
      "Keys in the change set (OcTree::numChangesDetected).");
  map.def(
      "changed_keys",
      [](Map& self) {
        const std::vector<ChangedKey> changes =
            self.run([](OccupancyMap& map) { return map.changedKeys(); });
        std::vector<std::uint16_t> keys(changes.size() * 3);
        std::vector<std::uint8_t> created(changes.size());
        for (std::size_t i = 0; i < changes.size(); ++i) {
          for (int c = 0; c < 3; ++c) keys[i * 3 + c] = changes[i].key[c];
          created[i] = changes[i].created ? 1 : 0;
        }
        const auto n = static_cast<py::ssize_t>(changes.size());
        return py::make_tuple(ownedArray(std::move(keys), {n, 3}),
                              ownedArray(std::move(created), {n}));
      },
      "The change set (OcTree::changedKeysBegin/End), in no particular order: (keys uint16 "
      "(N, 3), the finest-level OcTreeKeys (octovk.key_to_coord(map.resolution, keys) gives "
      "their cells' centres); created uint8 (N,), 1 where the leaf was created (OctoMap's "
      "True), 0 where its occupancy flipped (False)).");

  map.def(
      "node_count",
      [](Map& self) { return self.run([](OccupancyMap& map) { return map.nodeCount(); }); },
      "Nodes in the tree (OcTree::size()).");
  map.def(
      "leaf_count",
      [](Map& self) { return self.run([](OccupancyMap& map) { return map.leafCount(); }); },
      "Leaves of the tree (OcTree::getNumLeafNodes()).");
  map.def(
      "device_bytes",
      [](Map& self) {
        return deviceBytesTotal(self.run([](OccupancyMap& map) { return map.deviceBytesByUse(); }));
      },
      "Device bytes the map holds, all its buffers together (an int, C++'s deviceBytes()): what "
      "max_device_bytes caps. Its breakdown is device_bytes_by_use(); the fields pool, "
      "scratch, ... on this int are deprecated (it returned the breakdown before).");
  map.def(
      "device_bytes_by_use",
      [](Map& self) { return self.run([](OccupancyMap& map) { return map.deviceBytesByUse(); }); },
      "device_bytes() by use (DeviceBytes: pool, leaf_boxes, scratch, queries, changes, "
      "distance_fields, total; C++'s deviceBytesByUse()).");
  map.def(
      "cast_ray_info",
      [](Map& self) { return self.run([](OccupancyMap& map) { return map.castRayInfo(); }); },
      "castRay's backend on this map and its acceleration structure (CastRayInfo).");
  map.def(
      "spill_tiles",
      [](Map& self, bool to_file) {
        self.run([&](OccupancyMap& map) {
          map.spillTilesTo(to_file ? sqliteTileSpill() : makeHostTileSpill());
        });
      },
      py::arg("to_file") = true,
      "Lets the map outgrow max_device_bytes (C++'s spillTilesTo): where a scan needs more node "
      "pool than the cap allows, the tiles (16^3 cells) farthest from the sensor leave the "
      "device, into a temporary SQLite file (to_file=True, removed when the map goes) or host "
      "memory, and come back when a scan reaches them; the map stays OctoMap's, and write()/"
      "download include them. While tiles are off the device, queries, edits and distance "
      "fields raise ValueError.");
  map.def(
      "spilled_tiles",
      [](Map& self) { return self.run([](OccupancyMap& map) { return map.spilledTiles(); }); },
      "Tiles off the device now (spill_tiles), once the scans in flight are in; 0 when the whole "
      "map is on it.");
  map.def(
      "trim", [](Map& self) { self.run([](OccupancyMap& map) { map.trim(); }); },
      "Releases the per-scan scratch and the query buffers to an empty map's sizes (results "
      "do not change).");

  map.def_property_readonly(
      "context", [](const Map& self) { return self.context(); }, "The Context of the map.");
  map.def_property_readonly(
      "resolution", [](const Map& self) { return self.map().params().resolution; },
      "Edge of the finest cells, in metres.");
  map.def_property_readonly("prob_hit",
                            [](const Map& self) { return self.map().params().prob_hit; });
  map.def_property_readonly("prob_miss",
                            [](const Map& self) { return self.map().params().prob_miss; });
  map.def_property_readonly("clamping_min",
                            [](const Map& self) { return self.map().params().clamping_min; });
  map.def_property_readonly("clamping_max",
                            [](const Map& self) { return self.map().params().clamping_max; });
  map.def_property_readonly("occupancy_threshold", [](const Map& self) {
    return self.map().params().occupancy_threshold;
  });
  map.def_property_readonly("max_device_bytes",
                            [](const Map& self) { return self.map().params().max_device_bytes; });
  map.def("__repr__", [](const Map& self) {
    return "Map(resolution=" + std::to_string(self.map().params().resolution) + ")";
  });

  bindColorMap(m);
  bindStampedMap(m);
  bindStoreFollower(m);
  bindStoredMap(m);
}

}  // namespace octovk::python
