// The skeleton every octovk command runs in (command.cpp). A command says what is its own (a
// Subcommand: its name, help, input, outputs and options, and a Command: how it applies its own
// options, checks its command line and does its work); runSubcommand() does the rest the same
// way for all: --help, the command line (the one input, -o, --max-device-memory, unknown
// options and their errors), the output files and the Vulkan context. main.cpp dispatches to it
// and turns every error into its line on stderr and its exit code.
#pragma once

#include <cstddef>
#include <iosfwd>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "cli.hpp"

namespace octovk::cli {

struct Subcommand;

/// What the driver parsed and made for one run of a command.
class Invocation {
 public:
  explicit Invocation(const Subcommand& command) : command_(command) {}

  /// The one positional argument (a map file, a scan graph, a folder); empty when none was given.
  const std::string& input() const noexcept { return input_; }
  /// Each -o / --output, in order.
  const std::vector<std::string>& outputs() const noexcept { return outputs_; }
  /// The first -o; empty when none was given.
  const std::string& output() const;
  /// --max-device-memory (MapParams::max_device_bytes; 0 = no cap).
  std::size_t maxDeviceBytes() const noexcept { return max_device_bytes_; }

  /// Refuses (UsageError) a command line without -o, or an output whose name or place the
  /// command cannot write (checkOutputFile with the command's extensions).
  void checkOutputs() const;
  /// Adds an output named by one of the command's own options (integrate --changes), from
  /// Command::check: created, checked against the inputs and the other outputs, and committed
  /// with the -o outputs, all or nothing. Its index in files() is returned (after the -o ones).
  std::size_t addOptionOutput(const std::string& path);
  /// The checks of a command that reads a map file: the map (checkMapInput, with the command's
  /// `usage` line), --max-device-memory (checkDeviceMemoryCap) and the outputs (checkOutputs),
  /// if it writes any.
  void checkMapCommand(const std::string& usage) const;
  /// Refuses (UsageError) a --max-device-memory below what an empty map holds (default
  /// MapParams: for the commands that read a map, whose parameters come from the file).
  void checkDeviceMemoryCap() const;

  /// The Vulkan context, created at the first call (octovk::Error when there is none).
  Context& context();
  /// The output files, created by the driver once Command::check passed (see OutputFiles).
  OutputFiles& files();

 private:
  friend int runSubcommand(const Subcommand& command, const std::vector<std::string>& args);
  const Subcommand& command_;
  std::string input_;
  std::vector<std::string> outputs_;
  std::vector<std::string> option_outputs_;  // addOptionOutput
  std::size_t max_device_bytes_ = 0;
  std::unique_ptr<Context> context_;
  std::optional<OutputFiles> files_;
};

/// The map file of the invocation's input, read and checked on the host first (OctoMap's reader
/// chatter kept off stderr), then put on the invocation's device under --max-device-memory; a
/// cap's errors name the option (withOptionNames).
OccupancyMap loadMap(Invocation& in);

/// What a command does with its command line: the driver calls option() for every option it
/// does not know itself, then check(), creates the outputs, and calls run().
class Command {
 public:
  virtual ~Command() = default;
  /// Applies `option` if it is one of the command's own; false when it is not.
  virtual bool option(const ParsedOption& option) {
    (void)option;
    return false;
  }
  /// Checks the whole command line before any output is created or work done (UsageError).
  virtual void check(Invocation& invocation) { (void)invocation; }
  /// The work; returns the exit code. Errors are thrown (UsageError, octovk::Error).
  virtual int run(Invocation& invocation) = 0;
};

/// A command of the program as the driver and the help see it.
struct Subcommand {
  /// How many -o / --output it takes.
  enum class Outputs { kNone, kOne, kMany };

  const char* name;  ///< "render"
  /// What it does, in one line of the program's help ("a PNG picture of a map's occupied cells").
  const char* summary = "";
  void (*print_help)(std::ostream& out);  ///< its help, without the environment and exit codes
  /// What its one positional argument is, for the error on a second one ("map file"), and what
  /// that error adds after it ("; the picture goes after -o"). nullptr: the command takes no
  /// arguments at all.
  const char* input = nullptr;
  const char* second_input_hint = "";
  Outputs outputs = Outputs::kNone;
  /// What its one output is, for Outputs::kOne ("one picture"): the error on a second -o says so.
  const char* writes = "";
  /// The error on no -o, the extensions an output may have and their description in words
  /// (Invocation::checkOutputs).
  const char* no_output = "";
  std::vector<std::string> output_extensions;
  const char* output_formats = "";
  bool max_device_memory = false;  ///< takes --max-device-memory (Invocation::maxDeviceBytes)
  /// Its work is a few large batches (castRay per pixel, a field over a box), where lavapipe's
  /// worker threads pay; the others are streams of small dispatches, run without them unless
  /// LP_NUM_THREADS says otherwise (preferCpuDriverThreads).
  bool large_batches = false;
  /// Its own options that take one value, and those that take several (ArgReader); the names
  /// not listed are flags.
  std::vector<std::string> value_options;
  std::vector<std::pair<std::string, std::string>> multi_value_options;
  /// Ends the error on an unknown option, after "see 'octovk NAME --help'".
  const char* unknown_option_tail = " for the options";
  /// A fresh Command for one run.
  std::unique_ptr<Command> (*make)();
  /// Two or three command lines a user can start from, one per line, printed by the help.
  const char* examples = "";
  /// A command of actions (store export|follow|log|info) runs the words after its name itself, each
  /// action through runSubcommand; nullptr for the others.
  int (*run_actions)(const std::vector<std::string>& args) = nullptr;
};

/// Runs `command` on `args` (the words after its name): help, parsing, checks, outputs, work.
int runSubcommand(const Subcommand& command, const std::vector<std::string>& args);

/// Prints `command`'s help, then where the environment and the exit codes are described.
void printSubcommandHelp(const Subcommand& command, std::ostream& out);

/// The line that points to 'octovk help environment' (printEnvironmentAndExitCodes).
void printEnvironmentPointer(std::ostream& out);

/// Each command's help (without the environment and exit codes) and a fresh Command for one run,
/// defined in the command's own file (render.cpp: printRenderHelp, makeRender).
void printIntegrateHelp(std::ostream& out);
void printConvertHelp(std::ostream& out);
void printInfoHelp(std::ostream& out);
void printRenderHelp(std::ostream& out);
void printExportHelp(std::ostream& out);
void printEditHelp(std::ostream& out);
void printDistanceHelp(std::ostream& out);
void printDevicesHelp(std::ostream& out);
std::unique_ptr<Command> makeIntegrate();
std::unique_ptr<Command> makeConvert();
std::unique_ptr<Command> makeInfo();
std::unique_ptr<Command> makeRender();
std::unique_ptr<Command> makeExport();
std::unique_ptr<Command> makeEdit();
std::unique_ptr<Command> makeDistance();
std::unique_ptr<Command> makeDevices();
/// integrate's options that take one value (integrate.cpp).
std::vector<std::string> integrateValueOptions();

/// The program's commands, in the order the help and the errors list them (commands.cpp).
std::span<const Subcommand> subcommands();

}  // namespace octovk::cli
