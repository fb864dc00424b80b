// ColorMap and StampedMap: an OccupancyMap with a payload, and the calls that read or change it.
#include <string>

#include "map/host_memory.hpp"
#include "map/map_impl.hpp"
#include "octovk/map.hpp"

namespace octovk {

namespace {

MapParams withPayload(MapParams params, Payload payload) {
  params.payload = payload;
  return params;
}

OccupancyMap&& checkedPayload(OccupancyMap&& map, Payload payload, const char* call) {
  if (map.params().payload != payload)
    throw Error(ErrorCode::kInvalidArgument,
                std::string(call) + ": the map is a " + treeTypeName(map.params().payload) +
                    ", not a " + treeTypeName(payload) +
                    "; read a file of that tree type, or make the map with that payload");
  return std::move(map);
}

}  // namespace

ColorMap::ColorMap(Context& context, MapParams params)
    : OccupancyMap(context, withPayload(params, Payload::kColor)) {}

ColorMap::ColorMap(OccupancyMap&& map)
    : OccupancyMap(checkedPayload(std::move(map), Payload::kColor, "ColorMap")) {}

ScanStats ColorMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                     const Eigen::Vector3f& origin_world,
                                     std::span<const Rgb> colors, ScanOptions options) {
  options.colors = colors;
  return OccupancyMap::insertPointCloud(points_world, origin_world, options);
}

std::vector<Rgb> ColorMap::colors(std::span<const Eigen::Vector3f> points) {
  const std::vector<Lookup> found = search(points);
  std::vector<Rgb> out(found.size());
  for (std::size_t i = 0; i < found.size(); ++i)
    if (found[i].state != CellState::kUnknown) out[i] = unpackRgb(found[i].payload);
  return out;
}

StampedMap::StampedMap(Context& context, MapParams params)
    : OccupancyMap(context, withPayload(params, Payload::kStamp)) {}

StampedMap::StampedMap(OccupancyMap&& map)
    : OccupancyMap(checkedPayload(std::move(map), Payload::kStamp, "StampedMap")) {}

ScanStats StampedMap::insertPointCloud(std::span<const Eigen::Vector3f> points_world,
                                       const Eigen::Vector3f& origin_world, std::uint32_t stamp,
                                       ScanOptions options) {
  options.stamp = stamp;
  return OccupancyMap::insertPointCloud(points_world, origin_world, options);
}

std::vector<std::uint32_t> StampedMap::stamps(std::span<const Eigen::Vector3f> points) {
  const std::vector<Lookup> found = search(points);
  std::vector<std::uint32_t> out(found.size(), 0u);
  for (std::size_t i = 0; i < found.size(); ++i)
    if (found[i].state != CellState::kUnknown) out[i] = found[i].payload;
  return out;
}

}  // namespace octovk

namespace octovk {

void StampedMap::degradeOutdated(std::uint32_t now, std::uint32_t threshold_s) {
  hostMemoryGuard("degradeOutdated", [&] { self().degradeOutdated(now, threshold_s); });
}

std::uint32_t StampedMap::lastUpdateTime() {
  return hostMemoryGuard("lastUpdateTime", [&] { return self().rootPayload(); });
}

}  // namespace octovk
