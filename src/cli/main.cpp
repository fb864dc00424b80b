// octovk: the command-line program. Dispatches to a command; every failure ends here as one line
// on stderr and an exit code (the library never exits, and neither does a command).
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "cli.hpp"
#include "octovk/octovk.hpp"

namespace octovk::cli {
namespace {

// Commands that exist, for the help and for the error on an unknown one.
constexpr const char* kCommands = "integrate, convert, info, render, export, devices, help";

void printHelp(std::ostream& out) {
  out << "octovk: OctoMap-compatible occupancy mapping on a Vulkan device\n"
         "\n"
         "Usage:\n"
         "  octovk integrate SCANS.graph|DIR -o MAP.bt [-o MAP.ot] [options]\n"
         "  octovk convert DIR -o SCANS.graph [--intrinsics FX FY CX CY] [--depth-scale S]\n"
         "  octovk info MAP.bt|MAP.ot\n"
         "  octovk render MAP.bt|MAP.ot -o VIEW.png [--eye X Y Z] [--look-at X Y Z] [--size WxH]\n"
         "                [--fov DEG] [--z-max Z]\n"
         "  octovk export MAP.bt|MAP.ot -o CELLS.ply [--occupied-only] [--box X0 Y0 Z0 X1 Y1 Z1]\n"
         "                [--color height|occupancy]\n"
         "  octovk devices\n"
         "  octovk help [COMMAND]      (also: octovk --help, octovk COMMAND --help)\n"
         "\n"
         "Commands:\n"
         "  integrate   insert a scan graph, or a TUM RGB-D depth-image folder (DIR), into a map\n"
         "              and write .bt / .ot files, byte-identical to OctoMap's graph2tree\n"
         "  convert     write a TUM RGB-D folder as an OctoMap scan graph (.graph)\n"
         "  info        resolution, nodes, leaves (occupied / free), bounds and device memory of\n"
         "              a map file\n"
         "  render      a PNG picture of a map's occupied cells, ray cast on the device\n"
         "  export      a map's leaf cells (centre, size, log-odds, colour) as an ASCII PLY file\n"
         "  devices     list the Vulkan devices and the one octovk picks\n"
         "  help        this help, or a command's\n"
         "\n"
         "Each command's options: octovk COMMAND --help (or octovk help COMMAND).\n"
         "\n"
         "--- integrate ---\n";
  printIntegrateHelp(out);
  out << "\n";
  printEnvironmentAndExitCodes(out);
}

void printDevicesHelp(std::ostream& out) {
  out << "octovk devices\n"
         "\n"
         "Lists the Vulkan devices (index, name, type, device-local memory, ray tracing) and the\n"
         "one octovk would use now, which OCTOVK_DEVICE changes, with castRay's backend there.\n"
         "\n";
  printEnvironmentAndExitCodes(out);
}

int runDevices(const std::vector<std::string>& args) {
  if (wantsHelp(args)) {
    printDevicesHelp(std::cout);
    return kExitOk;
  }
  if (!args.empty())
    throw UsageError("devices takes no arguments (got '" + args.front() +
                     "'); run 'octovk devices'");
  const std::vector<DeviceInfo> devices = Context::listDevices();
  if (devices.empty())
    throw Error(ErrorCode::kNoDevice,
                "no Vulkan device found: install Mesa's CPU driver (apt-get install "
                "mesa-vulkan-drivers) or a GPU driver, and check 'vulkaninfo --summary'");
  for (const DeviceInfo& d : devices) {
    std::printf("%u: %s (%s), %.1f GiB device-local memory, %s\n", d.index, d.name.c_str(),
                d.type.c_str(), static_cast<double>(d.memory_bytes) / (1024.0 * 1024.0 * 1024.0),
                d.ray_query ? (d.ray_tracing_pipeline ? "ray queries and ray-tracing pipelines"
                                                      : "ray queries")
                            : "no ray tracing");
  }
  // Creating the context answers "which one would integrate use?", OCTOVK_DEVICE included.
  Result<std::unique_ptr<Context>> context = Context::create();
  if (!context) throw context.error();
  const DeviceInfo& selected = context.value()->device();
  // What a map with the default MapParams uses for castRay (render, the library's default).
  const OccupancyMap probe(*context.value(), MapParams{});
  std::printf("selected: %u: %s; castRay: %s\n", selected.index, selected.name.c_str(),
              probe.castRayInfo().backend == CastRayBackend::kRayTracing
                  ? "ray tracing (VK_KHR_acceleration_structure + VK_KHR_ray_query)"
                  : "compute walk");
  return kExitOk;
}

int runHelp(const std::vector<std::string>& args) {
  if (args.empty()) {
    printHelp(std::cout);
  } else if (args.front() == "integrate") {
    printIntegrateHelp(std::cout);
    std::cout << "\n";
    printEnvironmentAndExitCodes(std::cout);
  } else if (args.front() == "info" || args.front() == "render" || args.front() == "export" ||
             args.front() == "convert") {
    const auto print = args.front() == "info"     ? printInfoHelp
                       : args.front() == "render" ? printRenderHelp
                       : args.front() == "export" ? printExportHelp
                                                  : printConvertHelp;
    print(std::cout);
    std::cout << "\n";
    printEnvironmentAndExitCodes(std::cout);
  } else if (args.front() == "devices") {
    printDevicesHelp(std::cout);
  } else if (args.front() == "help") {
    printHelp(std::cout);
  } else {
    throw UsageError("no help for unknown command '" + args.front() + "'; commands: " + kCommands);
  }
  return kExitOk;
}

int dispatch(const std::vector<std::string>& args) {
  if (args.empty())
    throw UsageError(std::string("no command given; commands: ") + kCommands +
                     " (see 'octovk --help')");
  const std::string& command = args.front();
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (command == "-h" || command == "--help" || command == "help") return runHelp(rest);
  if (command == "integrate") return runIntegrate(rest);
  if (command == "convert") return runConvert(rest);
  if (command == "info") return runInfo(rest);
  if (command == "render") return runRender(rest);
  if (command == "export") return runExport(rest);
  if (command == "devices") return runDevices(rest);
  if (!command.empty() && command[0] == '-')
    throw UsageError("unknown option '" + command + "' before a command; commands: " + kCommands +
                     " (see 'octovk --help')");
  throw UsageError("unknown command '" + command + "'; commands: " + kCommands +
                   " (see 'octovk --help')");
}

// Library messages may hold line breaks (a device list); an error stays one line.
std::string oneLine(const std::string& message) {
  std::string out;
  for (std::size_t i = 0; i < message.size(); ++i) {
    const char c = message[i];
    if (c != '\n' && c != '\r') {
      out += c;
      continue;
    }
    while (i + 1 < message.size() &&
           (message[i + 1] == ' ' || message[i + 1] == '\n' || message[i + 1] == '\r'))
      ++i;
    if (!out.empty() && i + 1 < message.size()) out += out.back() == ':' ? " " : "; ";
  }
  return out;
}

// A standard stream closed by the caller gets a stand-in, so that no file opened later takes its
// number: the map written to fd 1 would receive the summary. stdout's stand-in is read-only, so
// that writes to it fail and are reported as a failure.
void reopenClosedStandardStreams() {
  for (const int fd : {STDIN_FILENO, STDOUT_FILENO, STDERR_FILENO}) {
    if (::fcntl(fd, F_GETFD) != -1 || errno != EBADF) continue;
    const int opened = ::open("/dev/null", fd == STDERR_FILENO ? O_WRONLY : O_RDONLY);
    if (opened >= 0 && opened != fd) {
      ::dup2(opened, fd);
      ::close(opened);
    }
  }
}

void printError(const std::string& message) {
  std::cout.flush();
  std::fprintf(stderr, "octovk: error: %s\n", oneLine(message).c_str());
  std::fflush(stderr);
}

}  // namespace
}  // namespace octovk::cli

int main(int argc, char** argv) {
  using namespace octovk::cli;
  reopenClosedStandardStreams();
  installSignalCleanup();
  try {
    const std::vector<std::string> args(argv + 1, argv + argc);
    const int status = dispatch(args);
    // What the user asked to see is part of the result: lost output is a failure.
    if (!flushStdout()) {
      const int why = errno;
      printError(why != 0 ? std::string("cannot write to standard output: ") + std::strerror(why)
                          : "cannot write to standard output (closed, full, or a write error)");
      return kExitFailure;
    }
    // Under OCTOVK_VALIDATION a message of the validation layer is a failure of the run.
    if (const std::size_t messages = octovk::validationMessageCount(); messages > 0) {
      printError(std::to_string(messages) +
                 " Vulkan validation message(s) (OCTOVK_VALIDATION is set); see above");
      return kExitFailure;
    }
    return status;
  } catch (const UsageError& e) {
    printError(e.what());
    return kExitUsage;
  } catch (const octovk::Error& e) {
    printError(e.what());
    return kExitFailure;
  } catch (const std::exception& e) {
    printError(std::string("unexpected failure: ") + e.what());
    return kExitFailure;
  } catch (...) {
    printError("unexpected failure of unknown type");
    return kExitFailure;
  }
}
