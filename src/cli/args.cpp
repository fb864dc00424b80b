// Command-line parsing, file checks and map loading shared by the octovk commands.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <ostream>

#include "cli.hpp"
#include "octovk/octomap_io.hpp"

namespace octovk::cli {

namespace fs = std::filesystem;

ArgReader::ArgReader(const std::vector<std::string>& args, std::vector<std::string> value_options,
                     std::vector<std::pair<std::string, std::string>> multi_value_options)
    : args_(args),
      value_options_(std::move(value_options)),
      multi_value_options_(std::move(multi_value_options)) {}

bool ArgReader::next() {
  if (at_ >= args_.size()) return false;
  const std::string& arg = args_[at_++];
  if (!options_done_ && arg == "--") {
    options_done_ = true;
    return next();
  }
  // A lone "-" and anything after "--" are names, not options.
  if (options_done_ || arg.size() < 2 || arg[0] != '-') {
    is_option_ = false;
    positional_ = arg;
    return true;
  }
  is_option_ = true;
  option_ = {};
  bool has_inline = false;
  const std::size_t eq = arg.find('=');
  if (arg.rfind("--", 0) == 0 && eq != std::string::npos) {
    option_.name = arg.substr(0, eq);
    option_.value = arg.substr(eq + 1);
    has_inline = true;
  } else {
    option_.name = arg;
  }
  const auto multi = std::find_if(multi_value_options_.begin(), multi_value_options_.end(),
                                  [&](const auto& m) { return m.first == option_.name; });
  if (multi != multi_value_options_.end()) {
    const std::string& names = multi->second;
    const auto count = static_cast<std::size_t>(std::count(names.begin(), names.end(), ' ') + 1);
    if (has_inline) {
      std::size_t start = 0;
      for (std::size_t comma; (comma = option_.value.find(',', start)) != std::string::npos;
           start = comma + 1)
        option_.values.push_back(option_.value.substr(start, comma - start));
      option_.values.push_back(option_.value.substr(start));
    } else {
      while (option_.values.size() < count && at_ < args_.size())
        option_.values.push_back(args_[at_++]);
    }
    if (option_.values.size() != count) {
      std::string commas = names;
      std::replace(commas.begin(), commas.end(), ' ', ',');
      throw UsageError("option " + option_.name + " needs " + std::to_string(count) +
                       " values; write " + option_.name + " " + names + " or " + option_.name +
                       "=" + commas);
    }
    option_.value = option_.values.front();
    return true;
  }
  const bool takes_value =
      std::find(value_options_.begin(), value_options_.end(), option_.name) != value_options_.end();
  if (takes_value && !has_inline) {
    // The next word is the value even when it starts with '-': "--max-range -1" must work.
    if (at_ >= args_.size())
      throw UsageError("option " + option_.name + " needs a value; write " + option_.name +
                       " VALUE");
    option_.value = args_[at_++];
  } else if (!takes_value && has_inline) {
    throw UsageError("option " + option_.name + " takes no value; write just " + option_.name);
  }
  if (takes_value) option_.values = {option_.value};
  return true;
}

namespace {

double parseNumberText(const std::string& name, const std::string& text,
                       const std::string& example) {
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  const bool whole = !text.empty() && end == text.c_str() + text.size();
  if (!whole || errno == ERANGE || !std::isfinite(value))
    throw UsageError(name + " expects a number, got '" + text + "'; e.g. " + name + " " + example);
  return value;
}

}  // namespace

double parseNumber(const ParsedOption& option, const std::string& example) {
  return parseNumberText(option.name, option.value, example);
}

std::vector<double> parseNumbers(const ParsedOption& option, const std::string& example) {
  std::vector<double> out;
  for (const std::string& text : option.values)
    out.push_back(parseNumberText(option.name, text, example));
  return out;
}

std::array<double, 6> parseBox(const ParsedOption& option, const std::string& example) {
  const std::vector<double> v = parseNumbers(option, example);
  for (int a = 0; a < 3; ++a)
    if (v[a] > v[a + 3])
      throw UsageError(option.name + ": the minimum " + std::string(1, "xyz"[a]) + " (" +
                       option.values[a] + ") is above the maximum (" + option.values[a + 3] +
                       "); write " + option.name + " XMIN YMIN ZMIN XMAX YMAX ZMAX");
  return {v[0], v[1], v[2], v[3], v[4], v[5]};
}

bool wantsHelp(const std::vector<std::string>& args) {
  for (const std::string& arg : args) {
    if (arg == "--") return false;
    if (arg == "-h" || arg == "--help") return true;
  }
  return false;
}

void printEnvironmentAndExitCodes(std::ostream& out) {
  out << "Environment:\n"
         "  OCTOVK_DEVICE   the Vulkan device to use: an index or a substring of a name, as\n"
         "                  listed by 'octovk devices'. Unset: the first Vulkan 1.2 device of\n"
         "                  the best kind: discrete GPU, integrated GPU, virtual GPU, then the\n"
         "                  CPU (Mesa's lavapipe).\n"
         "  LP_NUM_THREADS  lavapipe's worker threads (Mesa's variable). Unset, octovk sets it\n"
         "                  to 0 for integrate, info, export, edit, convert and devices: a scan\n"
         "                  is many small passes, which lavapipe's threads slowed down about 2x\n"
         "                  on 2 cores, and much more when other work kept the cores busy;\n"
         "                  render and distance (large batches) keep lavapipe's default, a\n"
         "                  thread per core. 'octovk devices' says what holds.\n"
         "  OCTOVK_CACHE_DIR  where a run keeps the device probe's verdict and the Vulkan\n"
         "                  pipeline cache for the next one (default $XDG_CACHE_HOME/octovk, else\n"
         "                  ~/.cache/octovk); a damaged or foreign record there is ignored.\n"
         "  OCTOVK_REPROBE=1  probe the device's arithmetic again instead of using the kept\n"
         "                  verdict.\n"
         "  OCTOVK_PIPELINE_CACHE=0  no persistent pipeline cache.\n"
         "  OCTOVK_TRACE_STARTUP=1  print what start-up costs, step by step, on stderr.\n"
         "\n"
         "Exit codes:\n"
         "  0  success\n"
         "  1  failure while working: corrupt or truncated input, Vulkan or device error,\n"
         "     a file could not be written (full disk); every existing output file is left as\n"
         "     it was and no new one is left behind. Also: standard output could not be\n"
         "     written (closed or full; the files are written by then)\n"
         "  2  usage error: unknown command or option, missing or bad value, missing input or\n"
         "     one that is not a regular file (a FIFO), an output file that cannot be created\n"
         "     (each is created before any work) or that is an input or another output (also\n"
         "     through a link); nothing is done\n"
         "  128+N  ended by signal N (SIGHUP, SIGINT, SIGTERM): the temporary files are\n"
         "     removed and every existing output file is left as it was\n"
         "Errors are one line on stderr starting with 'octovk: error: '. Temporary files are\n"
         "named .NAME.octovk.tmp-PID.EXT beside each output NAME; a later run on NAME removes\n"
         "those of a killed run (SIGKILL, a crash) whose process is gone.\n";
}

void checkRegularInput(const std::string& path, const std::string& what, const std::string& fix) {
  const auto cannotRead = [&] {
    return UsageError("cannot read " + what + " '" + path + "': " + std::strerror(errno) +
                      "; check its permissions");
  };
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT || errno == ENOTDIR)
      throw UsageError(what + " '" + path + "' does not exist; check the path");
    throw cannotRead();
  }
  if (S_ISDIR(st.st_mode)) throw UsageError(what + " '" + path + "' is a directory; " + fix);
  // Checked before opening: opening a FIFO for reading waits for a writer, possibly forever.
  const auto notRegular = [&] {
    return UsageError(what + " '" + path + "' is not a regular file (a pipe, device or socket); " +
                      fix);
  };
  if (!S_ISREG(st.st_mode)) throw notRegular();
  // O_NONBLOCK: should it have become a FIFO since, the open still returns at once.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw cannotRead();
  const bool regular = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
  ::close(fd);
  if (!regular) throw notRegular();
}

void checkMapInput(const std::string& path, const std::string& usage) {
  if (path.empty()) throw UsageError("no map file given; usage: " + usage);
  checkRegularInput(path, "map file", "give a .bt or .ot file");
  const std::string ext = fs::path(path).extension().string();
  if (ext != ".bt" && ext != ".ot")
    throw UsageError("map file '" + path + "' has unknown extension '" + ext +
                     "'; give an OctoMap .bt (binary) or .ot (full) file");
}

void checkOutputFile(const std::string& path, const std::vector<std::string>& extensions,
                     const std::string& formats) {
  const fs::path target(path);
  const std::string ext = target.extension().string();
  if (std::find(extensions.begin(), extensions.end(), ext) == extensions.end())
    throw UsageError("output '" + path + "' has unknown extension '" + ext + "'; name it " +
                     formats);
  std::error_code ec;
  if (fs::is_directory(target, ec))
    throw UsageError("output '" + path + "' is an existing directory; give a file name");
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  if (!fs::exists(dir, ec))
    throw UsageError("output directory '" + dir.string() + "' of '" + path +
                     "' does not exist; create it first (mkdir -p " + dir.string() + ")");
  if (!fs::is_directory(dir, ec))
    throw UsageError("output '" + path + "': '" + dir.string() +
                     "' is not a directory; choose another output path");
  // W_OK|X_OK also reports a read-only file system, which root's permissions do not bypass.
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw UsageError("cannot write into '" + dir.string() + "' for '" + path +
                     "': " + std::strerror(errno) + "; choose a writable directory");
}

bool flushStdout() {
  std::cout.flush();
  errno = 0;
  const bool flushed = std::fflush(stdout) == 0;
  return flushed && !std::ferror(stdout) && !std::cout.fail();
}

std::unique_ptr<Context> createContext() {
  Result<std::unique_ptr<Context>> context = Context::create();
  if (!context) throw context.error();
  return std::move(context.value());
}

StderrSilencer::StderrSilencer() {
  std::fflush(stderr);
  saved_ = ::dup(STDERR_FILENO);
  const int null_fd = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (saved_ >= 0 && null_fd >= 0) ::dup2(null_fd, STDERR_FILENO);
  if (null_fd >= 0) ::close(null_fd);
}

StderrSilencer::~StderrSilencer() {
  if (saved_ < 0) return;
  std::fflush(stderr);
  ::dup2(saved_, STDERR_FILENO);
  ::close(saved_);
}

float occupancyLogOdds(const MapParams& params) {
  const double p = params.occupancy_threshold;
  return static_cast<float>(std::log(p / (1.0 - p)));
}
}  // namespace octovk::cli
