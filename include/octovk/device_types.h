// The device layouts of the interop API (octovk/vulkan_interop.hpp): what a caller writes into
// its query buffers and reads back. Shared verbatim by C++ and octovk's GLSL shaders, like the
// library's internal layouts (src/gpu/gpu_types.h, which includes this file); the layout tests
// check both sides agree.
#ifndef OCTOVK_DEVICE_TYPES_H
#define OCTOVK_DEVICE_TYPES_H

#ifdef __cplusplus
#include <cstdint>
namespace octovk::gpu {
using uint = std::uint32_t;
#define OCTOVK_DEVICE_CONST static constexpr
#else
#define OCTOVK_DEVICE_CONST const
#endif

// Cell states of a point lookup.
OCTOVK_DEVICE_CONST uint kCellUnknown = 0u;
OCTOVK_DEVICE_CONST uint kCellFree = 1u;
OCTOVK_DEVICE_CONST uint kCellOccupied = 2u;

// Result of one point lookup (OctoMap's search). 16 B.
struct LookupResult {
  uint state;      // 4B (0)  kCellUnknown / kCellFree / kCellOccupied
  float log_odds;  // 4B (4)  of the node found (0 when unknown)
  uint depth;      // 4B (8)  depth of the node found (0 when unknown)
  uint payload;    // 4B (12) its payload word (packed colour or stamp; 0 when none)
};

// One castRay query. 40 B.
struct RayQuery {
  double max_range;     // 8B (0)  <= 0: unlimited (OctoMap's maxRange)
  float origin_x;       // 4B (8)
  float origin_y;       // 4B (12)
  float origin_z;       // 4B (16)
  float direction_x;    // 4B (20)
  float direction_y;    // 4B (24)
  float direction_z;    // 4B (28)
  uint ignore_unknown;  // 4B (32)
  uint pad0;            // 4B (36)
};

// RayResult::hit of a castRay whose walk did not finish within the continuations the host
// recorded (a driver that limits loops, and a pathological ray): never left as stale memory.
OCTOVK_DEVICE_CONST uint kRayUnfinished = 0xFFFFFFFFu;

// Result of one castRay. 16 B.
struct RayResult {
  uint hit;     // 4B (0)  1: an occupied cell was hit (castRay returned true)
  float end_x;  // 4B (4)  OctoMap's `end`: centre of the last cell visited
  float end_y;  // 4B (8)
  float end_z;  // 4B (12)
};

// One changed key (OctoMap's KeyBoolMap entry), as the change-set readers write them into a
// caller's buffer after a ChangedKeysHeader. 16 B.
struct ChangedKey {
  uint key_x;    // 4B (0)  OcTreeKey at the finest level
  uint key_y;    // 4B (4)
  uint key_z;    // 4B (8)
  uint created;  // 4B (12) 1: the leaf was created (OctoMap's `true`); 0: its occupancy flipped
};
// What precedes the ChangedKeys in a caller's buffer. 16 B.
struct ChangedKeysHeader {
  uint count;  // 4B (0)  entries written after the header
  uint pad0;   // 4B (4)
  uint pad1;   // 4B (8)
  uint pad2;   // 4B (12)
};

// Distance-field queries (DistanceField, octovk/distance.hpp): each query is 4 floats, a sphere's
// centre x, y, z and radius (0 for a point); each result one DistanceResult. squared_cells is
// one of these where the field has no distance for the query.
OCTOVK_DEVICE_CONST uint kDistanceOutside = 0xFFFFFFFFu;     // not in the field's box (or NaN)
OCTOVK_DEVICE_CONST uint kDistanceNoObstacle = 0xFFFFFFFEu;  // no occupied cell in the box

// Result of one distance query. 32 B.
struct DistanceResult {
  float distance;      // 4B (0)  metres, cell centre to the nearest occupied cell's centre, capped
                       //         at the field's max distance, minus the sphere's radius; -1 (OctoMap's
                       //         distanceValue_Error) outside the box
  float obstacle_x;    // 4B (4)  centre of the nearest occupied cell (NaN when there is none)
  float obstacle_y;    // 4B (8)
  float obstacle_z;    // 4B (12)
  float gradient_x;    // 4B (16) unit vector from the obstacle to the cell (0 on an obstacle, at
  float gradient_y;    // 4B (20) or beyond the max distance, outside the box)
  float gradient_z;    // 4B (24)
  uint squared_cells;  // 4B (28) exact squared distance in cells (not capped), or kDistance*
};

#ifdef __cplusplus
}  // namespace octovk::gpu
#endif
#undef OCTOVK_DEVICE_CONST

#endif  // OCTOVK_DEVICE_TYPES_H
