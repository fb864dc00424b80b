// octovk: an OctoMap-compatible occupancy octree that lives and is updated on a Vulkan device.
// The umbrella header: everything of the core API. Each part stands alone too:
//   octovk/errors.hpp   Error, ErrorCode, Result
//   octovk/params.hpp   MapParams, ScanOptions, Pose, the backends
//   octovk/context.hpp  Context (threads and lifetime), ContextOptions, DeviceInfo
//   octovk/scan.hpp     DepthImage, ScanStats, StageTimes
//   octovk/queries.hpp  Lookup, Ray, RayHit, QueryRequest, HostTree
//   octovk/map.hpp      OccupancyMap
//   octovk/distance.hpp DistanceField: the distance to the nearest obstacle over a box
// OctoMap files and trees: octovk/octomap_io.hpp; Vulkan buffers: octovk/vulkan_interop.hpp.
#pragma once

#include "octovk/context.hpp"
#include "octovk/distance.hpp"
#include "octovk/errors.hpp"
#include "octovk/map.hpp"
#include "octovk/params.hpp"
#include "octovk/queries.hpp"
#include "octovk/scan.hpp"
