// Uses only the core, octovk::octovk (pkg-config octovk): all of its headers, a map, a scan and a
// lookup, and proves that no OctoMap came with it: none of OctoMap's headers was included, and
// (linked with --no-as-needed, so every library of the link interface is loaded) no OctoMap
// library is loaded.
#include <link.h>

#include <octovk/device_types.h>
#include <octovk/octovk.hpp>
#include <octovk/vulkan_interop.hpp>

#include <cstring>
#include <string>

#include "consumer.hpp"

#if defined(OCTOMAP_TYPES_H) || defined(OCTOMAP_OCTREE_H) || defined(OCTOMATH_VECTOR3_H)
#error "octovk's core headers included OctoMap"
#endif

namespace {

int findOctomap(dl_phdr_info* info, size_t, void* found) {
  const char* name = info->dlpi_name;
  if (name && (std::strstr(name, "liboctomap") || std::strstr(name, "liboctomath"))) {
    *static_cast<std::string*>(found) = name;
    return 1;
  }
  return 0;
}

}  // namespace

int main() {
  std::string octomap_library;
  dl_iterate_phdr(findOctomap, &octomap_library);
  if (!octomap_library.empty())
    return consumer::fail("octovk::octovk brought OctoMap into the program: " + octomap_library);

  int exit_code = 0;
  auto context = consumer::context(exit_code);
  if (!context) return exit_code;
  octovk::OccupancyMap map(*context, octovk::MapParams{});
  if (std::string why = consumer::insertWall(map); !why.empty()) return consumer::fail(why);
  std::printf("consumer (core): %zu nodes on %s, no OctoMap loaded\n", map.nodeCount(),
              context->device().name.c_str());
  return 0;
}
