// octovk devices: the Vulkan devices octovk can use, and the one it picks.
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "command.hpp"
#include "octovk/octovk.hpp"

namespace octovk::cli {

void printDevicesHelp(std::ostream& out) {
  out << "octovk devices\n"
         "\n"
         "Lists the Vulkan devices (index, name, type, device-local memory, the ways it traces\n"
         "rays: ray queries, ray-tracing pipelines) and the one octovk would use now, which\n"
         "OCTOVK_DEVICE changes, with castRay's backend there (and --rays rt's way of tracing).\n";
}

// The ways a device can trace rays.
const char* rayTracingPaths(const DeviceInfo& d) {
  if (d.ray_query && d.ray_tracing_pipeline) return "ray queries and ray-tracing pipelines";
  if (d.ray_query) return "ray queries";
  if (d.ray_tracing_pipeline) return "ray-tracing pipelines";
  return "no ray tracing";
}

const char* backendName(CastRayBackend backend) {
  switch (backend) {
    case CastRayBackend::kRayQuery:
      return "ray tracing through ray queries (VK_KHR_acceleration_structure + VK_KHR_ray_query)";
    case CastRayBackend::kRayTracingPipeline:
      return "ray tracing through a ray-tracing pipeline (VK_KHR_acceleration_structure + "
             "VK_KHR_ray_tracing_pipeline)";
    default:
      return "compute walk";
  }
}

namespace {

// The commands whose Subcommand::large_batches is `large`, as "a, b and c" (from the table, so
// the line says what main() does).
std::string commandsWith(bool large) {
  std::vector<std::string> names;
  for (const Subcommand& c : subcommands())
    if (c.large_batches == large) names.emplace_back(c.name);
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i)
    out += (i == 0 ? "" : i + 1 == names.size() ? " and " : ", ") + names[i];
  return out;
}

class Devices final : public Command {
 public:
  int run(Invocation& in) override {
    const std::vector<DeviceInfo> devices = Context::listDevices();
    if (devices.empty())
      throw Error(ErrorCode::kNoDevice,
                  "no Vulkan device found: install Mesa's CPU driver (apt-get install "
                  "mesa-vulkan-drivers) or a GPU driver, and check 'vulkaninfo --summary'");
    for (const DeviceInfo& d : devices) {
      std::printf("%u: %s (%s), %.1f GiB device-local memory, %s\n", d.index, d.name.c_str(),
                  d.type.c_str(), static_cast<double>(d.memory_bytes) / (1024.0 * 1024.0 * 1024.0),
                  rayTracingPaths(d));
    }
    // Creating the context answers "which one would integrate use?", OCTOVK_DEVICE included.
    Context& context = in.context();
    const DeviceInfo& selected = context.device();
    // What a map with the default MapParams uses for castRay (render, the library's default),
    // and so for --rays rt: the same choice of the ray-tracing path.
    const OccupancyMap probe(context, MapParams{});
    std::printf("selected: %u: %s; castRay: %s\n", selected.index, selected.name.c_str(),
                backendName(probe.castRayInfo().backend));
    // Only lavapipe reads LP_NUM_THREADS; say what this and the other mapping commands ran with.
    if (selected.type == "CPU") {
      const CpuDriverThreads threads = cpuDriverThreads();
      if (threads.chosen_by_octovk)
        std::printf(
            "lavapipe threads: LP_NUM_THREADS=%s, octovk's choice for %s (%s keep "
            "lavapipe's default); set LP_NUM_THREADS to choose\n",
            threads.setting.c_str(), commandsWith(false).c_str(), commandsWith(true).c_str());
      else if (!threads.setting.empty())
        std::printf("lavapipe threads: LP_NUM_THREADS=%s, from the environment\n",
                    threads.setting.c_str());
      else
        std::printf("lavapipe threads: lavapipe's default (one per core)\n");
    }
    return kExitOk;
  }
};

}  // namespace

std::unique_ptr<Command> makeDevices() { return std::make_unique<Devices>(); }

}  // namespace octovk::cli
