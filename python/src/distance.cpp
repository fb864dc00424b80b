// octovk.DistanceField: the exact distance field over a box of a Map (octovk/distance.hpp), with
// batched queries returning numpy arrays, and a differentiable query for torch. Every call runs
// under its Map's lock with the GIL released, as the Map's own calls do; the field keeps its Map
// alive.
#include <pybind11/eval.h>

#include <cstring>
#include <optional>
#include <string>

#include "arrays.hpp"
#include "bindings.hpp"
#include "map.hpp"

namespace octovk::python {
namespace {

class Field {
 public:
  Field(py::object map_object, Map& map, DistanceField field)
      : map_object_(std::move(map_object)), map_(map), field_(std::move(field)) {}
  /// The field gives its bytes back to the map's accounting: under the map's lock.
  ~Field() {
    map_.run([&](OccupancyMap&) { field_.reset(); });
  }
  Field(const Field&) = delete;
  Field& operator=(const Field&) = delete;

  /// Runs `work` on the field under the map's lock, the GIL released.
  template <class Work>
  auto run(Work&& work) {
    return map_.run([&](OccupancyMap&) { return work(*field_); });
  }
  const py::object& map() const { return map_object_; }

 private:
  py::object map_object_;  // keeps the Map (and its device) alive while the field lives
  Map& map_;
  std::optional<DistanceField> field_;
};

}  // namespace
}  // namespace octovk::python

OCTOVK_PYTHON_CHECKED_CLASS(octovk::python::Field)

namespace octovk::python {
namespace {

// squared_cells as the caller's library has it: uint32, or for torch (which has no uint32 here)
// an int64 tensor, which holds OUTSIDE_CELLS and NO_OBSTACLE_CELLS as they are.
py::object squaredColumn(py::handle input, std::vector<std::uint32_t>&& squared,
                         std::vector<py::ssize_t> lead) {
  if (!isTorch(input)) return ownedArray(std::move(squared), std::move(lead));
  std::vector<std::int64_t> wide(squared.begin(), squared.end());
  return likeInput(input, ownedArray(std::move(wide), std::move(lead)));
}

// The samples as (distance, obstacle, gradient, squared_cells), one entry per point: `lead` is
// (N,), or (H, W) for an organised cloud, and obstacle and gradient add an axis of 3. Torch tensors
// (sharing the arrays' memory) where `input` is one, as Map.search answers.
py::tuple sampleArrays(py::handle input, const std::vector<DistanceSample>& samples,
                       std::vector<py::ssize_t> lead) {
  const std::size_t n = samples.size();
  std::vector<float> distance(n), obstacle(3 * n), gradient(3 * n);
  std::vector<std::uint32_t> squared(n);
  for (std::size_t i = 0; i < n; ++i) {
    const DistanceSample& s = samples[i];
    distance[i] = s.distance_m;
    for (int a = 0; a < 3; ++a) {
      obstacle[3 * i + static_cast<std::size_t>(a)] = s.obstacle[a];
      gradient[3 * i + static_cast<std::size_t>(a)] = s.gradient[a];
    }
    squared[i] = s.squared_cells;
  }
  std::vector<py::ssize_t> lead3 = lead;
  lead3.push_back(3);
  return py::make_tuple(likeInput(input, ownedArray(std::move(distance), lead)),
                        likeInput(input, ownedArray(std::move(obstacle), lead3)),
                        likeInput(input, ownedArray(std::move(gradient), lead3)),
                        squaredColumn(input, std::move(squared), lead));
}

constexpr const char* kFieldDoc =
    "An exact Euclidean distance field over a box of a Map, on the device "
    "(octovk::DistanceField), with dynamicEDT3D's DynamicEDTOctomap meaning: for every cell "
    "of the box at the finest resolution, the distance from its centre to the centre of the "
    "nearest occupied cell inside the box (pruned leaves count as each of their cells), "
    "capped at max_distance_m; the exact squared distance in cells, not capped.\n\n"
    "The field reads the map when it is made and at update(); between them it answers for "
    "the map as it was. It keeps its Map alive and runs under the Map's lock; its device "
    "bytes count under the Map's max_device_bytes (DeviceBytes.distance_fields).\n\n"
    "Query results: distance float32 (N,) in metres (minus the radius for clearances; "
    "OUTSIDE = -1 outside the box or for a NaN coordinate), obstacle float32 (N, 3) (the "
    "nearest occupied cell's centre; NaN where the box has none or outside), gradient float32 "
    "(N, 3) (the unit vector from that obstacle's centre to the query cell's centre, "
    "(cell - obstacle) / sqrt(squared_cells): the derivative of the Euclidean distance to "
    "that obstacle; zero on an obstacle, where the distance is capped and outside), "
    "squared_cells uint32 (N,) (exact; OUTSIDE_CELLS or NO_OBSTACLE_CELLS).";

// DistanceField.autograd_function(): a torch.autograd.Function whose forward is the field's
// distance and whose backward is the field's gradient (as nvblox_torch's ESDF query). Python
// source, run once torch is asked for: the module itself does not import torch.
constexpr const char* kTorchSource = R"(
import torch


class DistanceFunction(torch.autograd.Function):
    """Differentiable distance to the nearest obstacle: DistanceFunction.apply(points, field).

    points: a tensor (..., 3) of any float dtype and device; returns the field's distance at each
    point (metres, the shape of points without its last axis, points' dtype and device). Its
    gradient with respect to points is the field's gradient: the unit vector from the nearest
    obstacle's centre to the point's cell centre, zero on an obstacle, where the distance is
    capped and outside the box (which reads DistanceField.OUTSIDE, -1). The field answers per
    cell, so the distance is constant within a cell; the gradient is that of the Euclidean
    distance to the nearest obstacle, which finite differences over whole cells follow.
    """

    @staticmethod
    def forward(ctx, points, field):
        if points.shape[-1:] != (3,):
            raise ValueError("points must have shape (..., 3), got " + str(tuple(points.shape)))
        flat = points.detach().reshape(-1, 3).to(device="cpu", dtype=torch.float32).contiguous()
        distance, _, gradient, _ = field.distances(flat)  # tensors, as flat is one
        distance = distance.to(device=points.device, dtype=points.dtype)
        gradient = gradient.to(device=points.device, dtype=points.dtype)
        ctx.save_for_backward(gradient.reshape(points.shape))
        return distance.reshape(points.shape[:-1])

    @staticmethod
    def backward(ctx, grad_distance):
        (gradient,) = ctx.saved_tensors
        return grad_distance.unsqueeze(-1) * gradient, None
)";

py::object autogradFunction() {
  // Built once (under the GIL) and never destroyed: a static py::object would be released after
  // the interpreter is gone, and an attribute would show in the class's members.
  static py::object* function = nullptr;
  if (function == nullptr) {
    py::dict scope;
    scope["__builtins__"] = py::module_::import("builtins");
    scope["__name__"] = "octovk";
    py::exec(kTorchSource, scope);
    function = new py::object(scope["DistanceFunction"]);
  }
  return *function;
}

// The cap: max_distance_m, or the deprecated `max_distance` where given.
float maxDistanceOf(float max_distance_m, py::handle max_distance) {
  return renamed(max_distance_m, max_distance, "max_distance", "max_distance_m",
                 "metres, as C++'s DistanceFieldOptions::max_distance_m");
}

}  // namespace

void bindDistance(py::module_& m) {
  py::class_<Field> field(m, "DistanceField", kFieldDoc);
  field.attr("OUTSIDE") = DistanceSample::kOutside;
  field.attr("OUTSIDE_CELLS") = DistanceSample::kOutsideCells;
  field.attr("NO_OBSTACLE_CELLS") = DistanceSample::kNoObstacleCells;
  field.def(py::init([](py::object map_object, py::handle min, py::handle max, float max_distance_m,
                        bool treat_unknown_as_occupied, py::handle max_distance) {
              Map& map = map_object.cast<Map&>();
              if (min.is_none() != max.is_none())
                throw Error(ErrorCode::kInvalidArgument,
                            std::string("DistanceField: ") + (min.is_none() ? "max" : "min") +
                                " is given without " + (min.is_none() ? "min" : "max") +
                                "; give both corners of the box, or neither for the map's bounds");
              const DistanceFieldOptions options{
                  .max_distance_m = maxDistanceOf(max_distance_m, max_distance),
                  .treat_unknown_as_occupied = treat_unknown_as_occupied};
              std::optional<DistanceField> made;
              if (min.is_none()) {
                map.run([&](OccupancyMap& occupancy) { made.emplace(occupancy, options); });
              } else {
                const Eigen::Vector3f lo = toVector3(min, "min");
                const Eigen::Vector3f hi = toVector3(max, "max");
                map.run([&](OccupancyMap& occupancy) { made.emplace(occupancy, lo, hi, options); });
              }
              return std::make_unique<Field>(std::move(map_object), map, std::move(*made));
            }),
            py::arg("map"), py::arg("min") = py::none(), py::arg("max") = py::none(), py::kw_only(),
            py::arg("max_distance_m") = 2.0f, py::arg("treat_unknown_as_occupied") = true,
            py::arg("max_distance") = py::none(),
            "Builds the field over the box of `map` from the cell holding `min` to the cell "
            "holding `max` (3 numbers each, metres; OctoMap's coordToKey), on the device, after "
            "every scan submitted to the map; without min and max, over the map's bounds (every "
            "cell of its leaves) and one cell around them. max_distance_m: metres (> 0) at which "
            "distances are capped (max_distance: its deprecated name). treat_unknown_as_occupied "
            "(DynamicEDTOctomap's treatUnknownAsOccupied): True (the default) counts the cells "
            "the map does not know as obstacles, so no distance promises clearance through space "
            "no sensor saw (unseen space reads 0); False counts only occupied cells, and unknown "
            "space reads as free. Raises InvalidArgumentError for an inverted box, a NaN corner, "
            "a corner outside the map's key range, one corner without the other, an empty map "
            "without a box or max_distance_m <= 0; OutOfDeviceMemoryError (naming the box, the "
            "bytes and what to change) when the map's max_device_bytes or the device leaves no "
            "room.");
  field.def(
      "update", [](Field& self) { self.run([](DistanceField& f) { f.update(); }); },
      "Brings the field up to the map as it is now (every scan submitted before included), "
      "equal cell for cell to a field built afresh: on the device, redoing only the lines "
      "whose obstacles changed (octovk::DistanceField::update).");
  field.def(
      "distances",
      [](Field& self, py::handle points, bool copy) {
        const ArrayView pts(points, "points", Layout::kPoints, {DType::kFloat32},
                            copyArgument(copy));
        noteInput(pts.data());
        return sampleArrays(points,
                            self.run([&](DistanceField& f) { return f.distances(pts.points()); }),
                            pts.leading());
      },
      py::arg("points"), py::kw_only(), py::arg("copy") = false,
      "The field at each of points (float32 (N, 3), (H, W, 3) or (N, 4) with x, y, z first, as "
      "Map.search reads them): the answer of the cell holding the point, on the device. copy: as "
      "in Map.insert_point_cloud. Returns (distance, obstacle, gradient, squared_cells) (see the "
      "class), one entry per point ((N,), or (H, W) for an organised cloud); torch tensors "
      "(sharing the arrays' memory; squared_cells int64) when points is one.");
  field.def(
      "clearances",
      [](Field& self, py::handle spheres, bool copy) {
        const ArrayView s(spheres, "spheres", {DType::kFloat32}, {-1, 4}, false,
                          copyArgument(copy));
        noteInput(s.data());
        const std::span<const Eigen::Vector4f> view(static_cast<const Eigen::Vector4f*>(s.data()),
                                                    s.extent(0));
        return sampleArrays(spheres, self.run([&](DistanceField& f) { return f.clearances(view); }),
                            {static_cast<py::ssize_t>(s.extent(0))});
      },
      py::arg("spheres"), py::kw_only(), py::arg("copy") = false,
      "spheres (float32 (N, 4): centre x, y, z and radius, metres): the clearance, the "
      "distance at the centre's cell minus the radius (negative where the sphere reaches an "
      "obstacle), with the nearest obstacle and gradient. copy: as in Map.insert_point_cloud. "
      "Returns (distance, obstacle, gradient, squared_cells); torch tensors (sharing the "
      "arrays' memory; squared_cells int64) when spheres is one.");
  field.def(
      "download",
      [](Field& self) {
        DistanceField::Grid g = self.run([](DistanceField& f) { return f.download(); });
        const std::vector<py::ssize_t> shape = {g.size[2], g.size[1], g.size[0]};
        return py::make_tuple(ownedArray(std::move(g.squared_cells), shape),
                              ownedArray(std::move(g.nearest), shape));
      },
      "The whole field: (squared_cells, nearest), uint32 arrays indexed [z, y, x] from the "
      "box's first cell: the exact squared distance in cells to the nearest occupied cell "
      "(NO_OBSTACLE_CELLS where the box has none) and that cell's index x + size_x * (y + "
      "size_y * z) (NO_OBSTACLE_CELLS where none).");
  field.def_property_readonly(
      "size",
      [](Field& self) {
        const auto s = self.run([](DistanceField& f) { return f.size(); });
        return py::make_tuple(s[0], s[1], s[2]);
      },
      "Cells along x, y, z.");
  field.def_property_readonly(
      "min_key",
      [](Field& self) {
        const auto k = self.run([](DistanceField& f) { return f.minKey(); });
        return py::make_tuple(k[0], k[1], k[2]);
      },
      "The OctoMap key of the box's first cell (x, y, z).");
  field.def_property_readonly(
      "max_distance_m",
      [](Field& self) {
        return self.run([](DistanceField& f) { return f.options().max_distance_m; });
      },
      "Metres at which distances are capped.");
  field.def_property_readonly(
      "max_distance",
      [](Field& self) {
        warnDeprecated(
            "DistanceField.max_distance is deprecated: name it max_distance_m; the old name goes "
            "in the next release");
        return self.run([](DistanceField& f) { return f.options().max_distance_m; });
      },
      "The deprecated name of max_distance_m (a DeprecationWarning).");
  field.def_property_readonly(
      "treat_unknown_as_occupied",
      [](Field& self) {
        return self.run([](DistanceField& f) { return f.options().treat_unknown_as_occupied; });
      },
      "Whether unknown cells count as obstacles (the unknown-space rule the field was built "
      "with).");
  field.def_static(
      "autograd_function", &autogradFunction,
      "The torch.autograd.Function behind torch_distances (imports torch): "
      "apply(points, field) gives the field's distance at points (..., 3) and, backward, the "
      "field's gradient.");
  field.def(
      "torch_distances",
      [](Field& self, py::object points) {
        // The Python object of `self` (its registered instance), for the Function's forward.
        return autogradFunction().attr("apply")(points,
                                                py::cast(self, py::return_value_policy::reference));
      },
      py::arg("points"),
      "The distance at points (a torch tensor (..., 3), any float dtype and device), "
      "differentiable: a tensor of points' dtype and device and shape without the last axis, "
      "whose gradient with respect to points is the field's gradient (the unit vector from "
      "the nearest obstacle to the point's cell; zero on an obstacle, where capped and "
      "outside the box, which reads OUTSIDE). For spheres, subtract the radius in torch.");
  field.def(
      "device_bytes",
      [](Field& self) { return self.run([](DistanceField& f) { return f.deviceBytes(); }); },
      "Device bytes the field holds (its part of the map's cap).");
  field.def_property_readonly(
      "last_update_ms",
      [](Field& self) { return self.run([](DistanceField& f) { return f.lastUpdateMs(); }); },
      "Device time of the last build or update(), in milliseconds (0 without timestamps).");
  field.def_property_readonly(
      "map", [](const Field& self) { return self.map(); }, "The Map the field reads.");
}

}  // namespace octovk::python
