#include "map/tree_edits.hpp"

#include <cmath>
#include <string>

#include "map/buffer_sizes.hpp"
#include "map/query_runner.hpp"

namespace octovk {

namespace {

// The checks both edits make before anything is recorded: finite corners, min <= max.
void checkBox(const char* call, const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(min[i]) || !std::isfinite(max[i]))
      throw Error(ErrorCode::kInvalidArgument,
                  std::string(call) +
                      ": the box's corners must be finite numbers; the map is "
                      "unchanged");
    if (min[i] > max[i])
      throw Error(ErrorCode::kInvalidArgument,
                  std::string(call) + ": min is above max along axis " + std::to_string(i) + " (" +
                      std::to_string(min[i]) + " > " + std::to_string(max[i]) +
                      "); give the lower corner first. The map is unchanged");
  }
}

}  // namespace

void TreeEdits::clearBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
  // As OctoMap's iterator: a corner outside the map visits no leaf (updateInnerOccupancy runs).
  edit("clearBox", min, max, [&](const gpu::BoxQuery* box) {
    passes::recordClearBox(core_.rec, core_.queryParams(), box);
  });
}

void TreeEdits::keepBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max) {
  // As OctoMap's iterator: a corner outside the map visits no leaf, so nothing is kept.
  edit("keepBox", min, max, [&](const gpu::BoxQuery* box) {
    passes::recordKeepBox(core_.rec, core_.queryParams(), box);
    passes::recordClearBox(core_.rec, core_.queryParams(), nullptr);  // updateInnerOccupancy
  });
}

void TreeEdits::degrade(std::uint32_t now, std::uint32_t threshold) {
  if (core_.params.payload != Payload::kStamp)
    throw Error(ErrorCode::kInvalidArgument,
                "degradeOutdated: the map holds no time stamps; make a StampedMap");
  core_.ensureLeafBoxes();  // clear_box lists the blocks by depth in their buffer
  core_.stream.begin(core_.buffers.bindings);
  passes::recordDegrade(core_.rec, core_.queryParams(), now, threshold);
  core_.stream.submitAndWait();
  treeChanged();
}

template <typename Record>
void TreeEdits::edit(const char* call, const Eigen::Vector3f& min, const Eigen::Vector3f& max,
                     Record record) {
  checkBox(call, min, max);
  gpu::BoxQuery box{};
  const bool inside = boxKeys(core_.params.resolution, min, max, box);  // false: outside the map
  core_.buffers.ensureQueries(sizeof(box), sizes::kSmallQuery);
  core_.ensureLeafBoxes();  // clear_box lists the blocks by depth in their buffer
  core_.stream.begin(core_.buffers.bindings);
  record(inside ? &box : nullptr);
  core_.stream.submitAndWait();
  treeChanged();
}

void TreeEdits::treeChanged() {
  core_.leaf_boxes = LeafBoxes::kStale;
  core_.treeChanged();
}

}  // namespace octovk
