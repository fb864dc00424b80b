// The driver every octovk command runs in: help, the command line, the checks, the output files,
// the Vulkan context, then the command's own work (command.hpp).
#include "command.hpp"

#include <filesystem>
#include <iostream>

namespace octovk::cli {

namespace {

namespace fs = std::filesystem;

bool isOutputOption(const std::string& name) { return name == "-o" || name == "--output"; }

// The files a run reads, which no output may be: a TUM RGB-D folder's depth.txt and
// groundtruth.txt (its images are found only later), else the input itself.
std::vector<std::string> inputFiles(const std::string& input) {
  std::error_code ec;
  if (!input.empty() && fs::is_directory(input, ec))
    return {(fs::path(input) / "depth.txt").string(), (fs::path(input) / "groundtruth.txt").string()};
  return {input};
}

}  // namespace

const std::string& Invocation::output() const {
  static const std::string none;
  return outputs_.empty() ? none : outputs_.front();
}

void Invocation::checkOutputs() const {
  if (outputs_.empty()) throw UsageError(command_.no_output);
  for (const std::string& path : outputs_)
    checkOutputFile(path, command_.output_extensions, command_.output_formats);
}

std::size_t Invocation::addOptionOutput(const std::string& path) {
  option_outputs_.push_back(path);
  return outputs_.size() + option_outputs_.size() - 1;
}

void Invocation::checkDeviceMemoryCap() const {
  MapParams cap;  // only its max_device_bytes: the rest comes from the map file
  cap.max_device_bytes = max_device_bytes_;
  cli::checkDeviceMemoryCap(cap);
}

Context& Invocation::context() {
  if (!context_) context_ = createContext();
  return *context_;
}

OutputFiles& Invocation::files() {
  if (!files_) throw Error(ErrorCode::kInternal, std::string(command_.name) + " has no output files");
  return *files_;
}

void printSubcommandHelp(const Subcommand& command, std::ostream& out) {
  command.print_help(out);
  out << "\n";
  printEnvironmentAndExitCodes(out);
}

int runSubcommand(const Subcommand& command, const std::vector<std::string>& args) {
  if (wantsHelp(args)) {
    printSubcommandHelp(command, std::cout);
    return kExitOk;
  }
  const std::string name = command.name;
  if (command.input == nullptr && !args.empty())
    throw UsageError(name + " takes no arguments (got '" + args.front() + "'); run 'octovk " +
                     name + "'");
  const std::unique_ptr<Command> own = command.make();
  Invocation in(command);

  std::vector<std::string> value_options = command.value_options;
  if (command.outputs != Subcommand::Outputs::kNone) {
    value_options.push_back("-o");
    value_options.push_back("--output");
  }
  if (command.max_device_memory) value_options.push_back(kMaxDeviceMemoryOption);
  ArgReader reader(args, value_options, command.multi_value_options);
  while (reader.next()) {
    if (!reader.isOption()) {
      if (!in.input_.empty())
        throw UsageError("unexpected argument '" + reader.positional() + "': " + name +
                         " takes one " + command.input + " (" + in.input_ + ")" +
                         command.second_input_hint);
      in.input_ = reader.positional();
      continue;
    }
    const ParsedOption& option = reader.option();
    if (command.outputs == Subcommand::Outputs::kMany && isOutputOption(option.name)) {
      in.outputs_.push_back(option.value);
    } else if (command.outputs == Subcommand::Outputs::kOne && isOutputOption(option.name)) {
      // An empty value counts as none given (checkOutputs asks for one).
      if (!in.outputs_.empty()) throw UsageError(command.output_twice(in.output(), option.value));
      if (!option.value.empty()) in.outputs_.push_back(option.value);
    } else if (command.max_device_memory && option.name == kMaxDeviceMemoryOption) {
      in.max_device_bytes_ = parseByteCount(option);
    } else if (!own->option(option)) {
      throw UsageError("unknown option '" + option.name + "' for " + name + "; see 'octovk " +
                       name + " --help'" + command.unknown_option_tail);
    }
  }
  own->check(in);
  // Every output is created now, so an unwritable one is found before any work.
  std::vector<std::string> outputs = in.outputs_;
  outputs.insert(outputs.end(), in.option_outputs_.begin(), in.option_outputs_.end());
  if (!outputs.empty()) in.files_.emplace(outputs, inputFiles(in.input_));
  return own->run(in);
}

}  // namespace octovk::cli
