// The driver every octovk command runs in: help, the command line, the checks, the output files,
// the Vulkan context, then the command's own work (command.hpp).
#include "command.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iostream>
#include <string_view>

#include "octovk/octomap_io.hpp"

namespace octovk::cli {

namespace {

namespace fs = std::filesystem;

bool isOutputOption(const std::string& name) { return name == "-o" || name == "--output"; }

// The files a run reads, which no output may be: a TUM RGB-D folder's depth.txt and
// groundtruth.txt (its images are found only later), else the input itself.
std::vector<std::string> inputFiles(const std::string& input) {
  std::error_code ec;
  if (!input.empty() && fs::is_directory(input, ec))
    return {(fs::path(input) / "depth.txt").string(),
            (fs::path(input) / "groundtruth.txt").string()};
  return {input};
}

// The option names `command` takes: those its help lists at the start of a line (flags are known
// only there), the value options, -o and --max-device-memory.
std::vector<std::string> knownOptions(const Subcommand& command) {
  std::ostringstream help;
  command.print_help(help);
  std::vector<std::string> names = command.value_options;
  for (const auto& multi : command.multi_value_options) names.push_back(multi.first);
  if (command.outputs != Subcommand::Outputs::kNone) names.insert(names.end(), {"-o", "--output"});
  if (command.max_device_memory) names.push_back(kMaxDeviceMemoryOption);
  std::istringstream lines(help.str());
  for (std::string line; std::getline(lines, line);) {
    // "  -r, --resolution M" or "      --prob-hit P"; deeper lines continue a description.
    const std::size_t start = line.find_first_not_of(' ');
    if (start == 0 || start == std::string::npos || start > 6 || line[start] != '-') continue;
    std::istringstream words(line.substr(start));
    for (std::string word; words >> word && word.size() > 1 && word[0] == '-';) {
      const bool more = word.back() == ',';
      if (more) word.pop_back();
      names.push_back(word.substr(0, word.find_first_of("=[|")));
      if (!more) break;
    }
  }
  std::sort(names.begin(), names.end());
  names.erase(std::unique(names.begin(), names.end()), names.end());
  return names;
}

// Edits (insert, delete, replace, swap two neighbours) that turn `a` into `b`.
std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min(
          {d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

std::string stripDashes(const std::string& name) {
  return name.substr(std::min(name.find_first_not_of('-'), name.size()));
}

// "did you mean --resolution?" for an unknown option: OctoMap's graph2tree spellings (-res,
// -discretize, -clamping, -sensor, -i), a long name with one dash, a prefix or a near miss.
std::string suggestion(const Subcommand& command, const std::string& unknown) {
  const std::vector<std::string> known = knownOptions(command);
  const auto has = [&](const std::string& name) {
    return std::find(known.begin(), known.end(), name) != known.end();
  };
  const auto ask = [](const std::vector<std::string>& names, const char* join) {
    std::string text = "did you mean ";
    for (std::size_t i = 0; i < names.size(); ++i)
      text += (i == 0 ? "" : i + 1 == names.size() ? join : ", ") + names[i];
    return text + "?";
  };
  if (unknown == "-i" && command.input != nullptr)
    return std::string("the ") + command.input + " needs no option: write 'octovk " + command.name +
           " INPUT ...', not graph2tree's -i INPUT";
  if (unknown == "-clamping" && has("--clamping-min"))
    return ask({"--clamping-min A", "--clamping-max B"}, " and ");
  if (unknown == "-sensor" && has("--prob-hit"))
    return ask({"--prob-miss A", "--prob-hit B"}, " and ");
  std::string bare = stripDashes(unknown);
  std::transform(bare.begin(), bare.end(), bare.begin(), [](unsigned char c) {
    return c == '_' ? '-' : static_cast<char>(std::tolower(c));
  });
  if (bare.empty()) return "";
  if (has("--" + bare)) return ask({"--" + bare}, " or ");
  if (bare.size() == 1 && has("-" + bare)) return ask({"-" + bare}, " or ");
  std::vector<std::string> found;
  if (bare.size() >= 2)
    for (const std::string& name : known)
      if (name.rfind("--" + bare, 0) == 0) found.push_back(name);
  if (!found.empty()) return ask(found, " or ");
  std::size_t best = bare.size() / 3 + 1;  // beyond that, a guess would mislead
  best = std::min<std::size_t>(best, 3);
  for (const std::string& name : known) {
    if (name.rfind("--", 0) != 0) continue;
    const std::size_t d = editDistance(bare, stripDashes(name));
    if (d < best) {
      found.clear();
      best = d;
    }
    if (d == best) found.push_back(name);
  }
  return found.empty() ? "" : ask(found, " or ");
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

void Invocation::checkMapCommand(const std::string& usage) const {
  checkMapInput(input_, usage);
  checkDeviceMemoryCap();
  if (command_.outputs != Subcommand::Outputs::kNone) checkOutputs();
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

OccupancyMap loadMap(Invocation& in) {
  // The file first, then the device: a damaged file is reported without starting a driver (which
  // may itself fail, e.g. NVIDIA's under `ulimit -v 4G`, and take the file's error with it).
  MapFileContents file;
  {
    StderrSilencer silenced;
    try {
      file = readMapFileContents(in.input());
    } catch (const Error& e) {
      throw withOptionNames(e);
    }
  }
  file.params.max_device_bytes = in.maxDeviceBytes();
  Context& context = in.context();
  StderrSilencer silenced;
  try {
    OccupancyMap map(context, file.params);
    map.upload(file.tree);
    return map;
  } catch (const Error& e) {
    throw withOptionNames(e);
  }
}

OutputFiles& Invocation::files() {
  if (!files_)
    throw Error(ErrorCode::kInternal, std::string(command_.name) + " has no output files");
  return *files_;
}

void printSubcommandHelp(const Subcommand& command, std::ostream& out) {
  command.print_help(out);
  out << "\nExamples:\n" << command.examples << "\n";
  printEnvironmentPointer(out);
  // The long explanations (formats, layouts, equivalents) live in the reference, not here.
  const std::string_view name = command.name;
  const char* section = name == "info" || name == "render" || name == "export"
                            ? "info, render, export"
                        : name == "convert" ? "integrate', 'Depth images (TUM RGB-D)"
                        : name == "devices" ? "devices and the device"
                                            : command.name;
  out << "Details: docs/cli.md, '" << section << "'.\n";
}

void printEnvironmentPointer(std::ostream& out) {
  // Once for the program, not in every command's help: about 35 lines each.
  out << "Exit codes (0 success, 1 failure, 2 usage error, 128+N signal N) and environment\n"
         "variables (OCTOVK_DEVICE, LP_NUM_THREADS, ...): octovk help environment\n";
}

int runSubcommand(const Subcommand& command, const std::vector<std::string>& args) {
  if (command.run_actions) return command.run_actions(args);
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
      if (!in.outputs_.empty())
        throw UsageError(std::string(command.name) + " writes " + command.writes +
                         "; give -o once (got '" + in.output() + "' and '" + option.value + "')");
      if (!option.value.empty()) in.outputs_.push_back(option.value);
    } else if (command.max_device_memory && option.name == kMaxDeviceMemoryOption) {
      in.max_device_bytes_ = parseByteCount(option);
    } else if (!own->option(option)) {
      if (const std::string guess = suggestion(command, option.name); !guess.empty())
        throw UsageError("unknown option '" + option.name + "' for " + name + "; " + guess +
                         " (see 'octovk " + name + " --help')");
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
