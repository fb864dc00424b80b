// octovk: the command-line program. Dispatches to a command; every failure ends here as one line
// on stderr and an exit code (the library never exits, and neither does a command).
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "command.hpp"
#include "octovk/octovk.hpp"

namespace octovk::cli {
namespace {

// The commands' names, for the error on an unknown one: "integrate, convert, ..., help, version".
std::string commandNames() {
  std::string names;
  for (const Subcommand& command : subcommands()) names += std::string(command.name) + ", ";
  return names + "help, version";
}

const Subcommand* findSubcommand(const std::string& name) {
  for (const Subcommand& command : subcommands())
    if (name == command.name) return &command;
  return nullptr;
}

// What octovk is, its commands one line each, where to start and where to read on; each
// command's options are in its own help.
void printHelp(std::ostream& out) {
  out << "octovk: OctoMap-compatible occupancy mapping on a Vulkan device (a GPU, or the CPU\n"
         "through Mesa's lavapipe). Maps are OctoMap's .bt / .ot files, byte for byte.\n"
         "\n"
         "Usage: octovk COMMAND [ARGS] [OPTIONS]\n"
         "\n"
         "Commands:\n";
  for (const Subcommand& command : subcommands()) {
    std::string name = command.name;
    name.resize(std::max<std::size_t>(name.size() + 1, 11), ' ');
    out << "  " << name << command.summary << "\n";
  }
  out << "  help       this help, a command's (octovk help COMMAND), or 'octovk help environment'\n"
         "  version    the program's version (also: octovk --version)\n"
         "\n"
         "Examples:\n"
         "  octovk integrate scans.graph -o map.bt -r 0.05\n"
         "  octovk info map.bt\n"
         "  octovk render map.bt -o view.png\n"
         "\n"
         "Each command's options and examples: octovk COMMAND --help.\n";
  printEnvironmentPointer(out);
}

int runHelp(const std::vector<std::string>& args) {
  if (args.empty() || args.front() == "help") {
    printHelp(std::cout);
  } else if (args.front() == "environment" || args.front() == "exit-codes") {
    printEnvironmentAndExitCodes(std::cout);
  } else if (const Subcommand* command = findSubcommand(args.front())) {
    printSubcommandHelp(*command, std::cout);
  } else {
    throw UsageError("no help for unknown command '" + args.front() +
                     "'; commands: " + commandNames() + "; also: octovk help environment");
  }
  return kExitOk;
}

int dispatch(const std::vector<std::string>& args) {
  if (args.empty())
    throw UsageError("no command given; commands: " + commandNames() + " (see 'octovk --help')");
  const std::string& command = args.front();
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (command == "-h" || command == "--help" || command == "help") return runHelp(rest);
  if (command == "--version" || command == "version") {
    if (!rest.empty())
      throw UsageError(command + " takes no arguments (got '" + rest.front() +
                       "'); run 'octovk --version'");
    std::cout << "octovk " << OCTOVK_VERSION << "\n";
    return kExitOk;
  }
  if (const Subcommand* found = findSubcommand(command)) {
    if (!found->large_batches) preferCpuDriverThreads(0);  // before the driver loads
    return runSubcommand(*found, rest);
  }
  if (!command.empty() && command[0] == '-')
    throw UsageError("unknown option '" + command +
                     "' before a command; commands: " + commandNames() + " (see 'octovk --help')");
  throw UsageError("unknown command '" + command + "'; commands: " + commandNames() +
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
