// DistanceField::Impl: the field's buffers (own, counted under the map's cap), its command
// stream and binding set, and the host side of building, updating and querying it. The passes
// it records are in field_passes.cpp; the map is only read (its node pool) through
// OccupancyMap::Impl::fieldBuffers() after a flush.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "map/map_impl.hpp"
#include "octovk/distance.hpp"
#include "vk/device.hpp"

namespace octovk {

/// The map's Impl, for the field (OccupancyMap befriends this class).
class FieldAccess {
 public:
  static OccupancyMap::Impl& impl(OccupancyMap& map) { return map.self(); }
};

/// The box of a field in keys: the cells from the key of `min` to the key of `max` (OctoMap's
/// coordToKey, as DynamicEDTOctomap), checked; throws kInvalidArgument naming the bad input.
struct FieldBox {
  std::array<std::uint32_t, 3> min_key{}, size{};
  std::size_t cells() const { return std::size_t{size[0]} * size[1] * size[2]; }
  /// Occupancy words of one x-line (32 cells each) and of the box.
  std::uint32_t wordsPerRow() const { return (size[0] + 31) / 32; }
  std::size_t words() const { return std::size_t{wordsPerRow()} * size[1] * size[2]; }
  /// Words of the three dirty bitmaps (x-, y-, z-lines), each rounded up to whole words.
  std::array<std::size_t, 3> dirtyWords() const {
    const auto w = [](std::size_t bits) { return (bits + 31) / 32; };
    return {w(std::size_t{size[1]} * size[2]), w(std::size_t{size[0]} * size[2]),
            w(std::size_t{size[0]} * size[1])};
  }
};
/// `name`: how the box is called in its errors ("the box" where the caller gave it).
FieldBox fieldBox(double resolution, const Eigen::Vector3f& min, const Eigen::Vector3f& max,
                  const DistanceFieldOptions& options, std::uint32_t max_line_cells,
                  const std::string& name);

/// The most cells a line of the box may have on `device`: field_edt walks a line in one loop
/// of edtLoopIterations(n), which must stay within the driver's loop budget, and its integers
/// stay below 2^31 up to gpu::kFieldMaxAxisCells.
std::uint32_t maxLineCells(const vk::Device& device);

/// Device bytes a field over `box` holds without query buffers.
std::size_t fieldBytes(const FieldBox& box);

class DistanceField::Impl {
 public:
  Impl(OccupancyMap::Impl& map, const FieldBox& box, const DistanceFieldOptions& options);
  ~Impl();
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  /// Brings the field up to the map (on the device, waited for): a build reads the whole tree
  /// (field_raster) and transforms every line; an update reads the cells of the change set
  /// (field_changes) where fromChanges(), else the whole tree again (field_raster comparing),
  /// and transforms the lines marked dirty. The first update() after the build
  /// turns change detection on (`building`: the constructor's, which does not).
  void update(bool building = false);
  /// Queries of 4 floats each (centre, radius) from the host.
  std::vector<DistanceSample> query(std::span<const float> spheres, std::size_t count);
  /// The same between ranges of a caller's buffers (interop): `count` spheres at `in`,
  /// DistanceResults to `out`; the first submission waits for `wait`.
  void queryOnDevice(VkBuffer in, VkDeviceSize in_offset, VkBuffer out, VkDeviceSize out_offset,
                     std::uint32_t count, VkSemaphore wait, std::uint64_t wait_value);
  DistanceField::Grid download();

  /// The map the field reads (interop: a caller's semaphore is signalled on its stream), wherever
  /// it was moved to; kInvalidArgument once it is destroyed.
  OccupancyMap::Impl& map() { return liveMap(); }
  vk::Device& device() const { return device_; }
  const FieldBox& box() const { return box_; }
  const DistanceFieldOptions& options() const { return options_; }
  std::size_t deviceBytes() const { return bytes_; }
  double lastUpdateMs() const { return last_ms_; }
  DistanceField::UpdateKind lastUpdateKind() const { return last_kind_; }

 private:
  OccupancyMap::Impl& liveMap();
  /// Query buffers for up to `count` queries per batch: as many as the cap has room for (at
  /// least one, else BudgetError), at most batchLimit().
  void ensureQueries(std::size_t count);
  /// Points the binding set at the field's buffers and the map's node pool as it is now.
  void rebind(MapBuffers& map);
  /// Spheres per submission: what one descriptor binding of results may hold.
  std::size_t batchLimit() const;
  void checkFresh(const char* call) const;
  /// Whether the next update may read the obstacles from the change set (else the whole tree).
  bool fromChanges();

  // First, so released last: the field's buffers and stream go before the device can.
  std::shared_ptr<vk::Device> device_owner_;
  std::shared_ptr<OccupancyMap::Impl*> map_;  // null once the map is destroyed
  vk::Device& device_;
  FieldBox box_;
  DistanceFieldOptions options_;
  vk::CommandStream stream_;
  vk::BindingSet bindings_;
  vk::Buffer params_;  // gpu::ScanParams: resolution and occupancy threshold (keys.glsl)
  vk::Buffer spare_;   // bound where the passes read nothing (counters, the scan's arrays)
  vk::Buffer header_;  // gpu::FieldHeader
  // gpu::FieldHeader's arrays: occupancy bits, line_x, plane_xy, sites, envelope, dirty bitmaps
  vk::Buffer occupancy_, line_x_, plane_xy_, sites_, envelope_, dirty_;
  vk::Buffer readback_;  // host-visible: the header after a build
  vk::Buffer query_in_, query_out_, staging_in_, staging_out_;
  std::size_t query_capacity_ = 0;
  std::size_t bytes_ = 0;  // noted in the map's cap accounting
  double last_ms_ = 0.0;
  bool stale_ = false;  // an update failed on the device: queries refuse until one succeeds
  bool built_ = false;  // the arrays hold the map as of `tracking_`
  OccupancyMap::Impl::FieldTracking tracking_;
  DistanceField::UpdateKind last_kind_ = DistanceField::UpdateKind::kBuild;
  bool follows_changes_ = false;  // counted in the map's change_set_fields
  bool reset_changes_ = false;    // the last update ended by emptying the change set
};

}  // namespace octovk
