// The octovk program's pieces shared between its commands: usage errors, option values, help.
#pragma once

#include <cstddef>
#include <functional>
#include <iosfwd>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "octovk/octovk.hpp"
#include "octovk/tum_sequence.hpp"

namespace octovk::cli {

/// A mistake in the command line (exit code 2). The message names the problem and the fix.
class UsageError : public std::runtime_error {
 public:
  explicit UsageError(const std::string& message) : std::runtime_error(message) {}
};

/// Exit codes, as documented in the help text.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 2;

/// One command-line option as `--name value`, `--name=value` or a bare flag.
struct ParsedOption {
  std::string name;   ///< "--resolution", "-o"
  std::string value;  ///< empty for flags; the first of `values` for a multi-value option
  std::vector<std::string> values;  ///< every value (one for a single-value option)
};

/// Walks `args` and splits them into options and positional arguments. `value_options` says which
/// option names consume a value, `multi_value_options` which consume several, with the names of
/// the values ({"--eye", "X Y Z"}: "--eye 1 2 3" or "--eye=1,2,3"); names not listed are flags.
/// Unknown names are kept for the caller to reject with its own list. "--" ends the options.
class ArgReader {
 public:
  ArgReader(const std::vector<std::string>& args, std::vector<std::string> value_options,
            std::vector<std::pair<std::string, std::string>> multi_value_options = {});

  /// The next option or positional argument; false at the end.
  bool next();
  bool isOption() const noexcept { return is_option_; }
  const ParsedOption& option() const noexcept { return option_; }
  const std::string& positional() const noexcept { return positional_; }

 private:
  const std::vector<std::string>& args_;
  std::vector<std::string> value_options_;
  std::vector<std::pair<std::string, std::string>> multi_value_options_;
  std::size_t at_ = 0;
  bool options_done_ = false;
  bool is_option_ = false;
  ParsedOption option_;
  std::string positional_;
};

/// `text` as a finite double, or a UsageError that names the option and gives `example`.
double parseNumber(const ParsedOption& option, const std::string& example);

/// Every value of a multi-value option as a finite double (see parseNumber).
std::vector<double> parseNumbers(const ParsedOption& option, const std::string& example);

/// True when `args` asks for help (-h / --help before any "--").
bool wantsHelp(const std::vector<std::string>& args);

/// If `args` ask for help, prints the command's help (`print`) and the environment and exit
/// codes on stdout, and returns true.
bool printHelpIfAsked(const std::vector<std::string>& args, void (*print)(std::ostream&));

/// The help of `octovk integrate`: usage, every option with its default, files, exit codes.
void printIntegrateHelp(std::ostream& out);
/// `octovk integrate ARGS...` (without the command name). Throws UsageError or octovk::Error.
int runIntegrate(const std::vector<std::string>& args);

/// `octovk info MAP`: what a map file holds.
void printInfoHelp(std::ostream& out);
int runInfo(const std::vector<std::string>& args);

/// `octovk render MAP -o VIEW.png`: a picture of the occupied cells, ray cast on the device.
void printRenderHelp(std::ostream& out);
int runRender(const std::vector<std::string>& args);

/// `octovk export MAP -o CELLS.ply`: the leaf cells as a point cloud for other viewers.
void printExportHelp(std::ostream& out);
int runExport(const std::vector<std::string>& args);

/// `octovk convert DIR -o SCANS.graph`: a TUM RGB-D folder as an OctoMap scan graph.
void printConvertHelp(std::ostream& out);
int runConvert(const std::vector<std::string>& args);

/// The environment and exit-code sections every help text ends with.
void printEnvironmentAndExitCodes(std::ostream& out);

// ---- files and maps, shared by the commands that read a map ----

/// Checks a map file given to `command` before any work: given, a .bt or .ot name, an existing
/// readable file. Throws UsageError naming the problem; `usage` is the command's usage line.
void checkMapInput(const std::string& path, const std::string& usage);

/// Checks that `path` can be created: its extension is one of `extensions` (".png"), it is not a
/// directory, and its directory exists and is writable. `formats` names the extensions in words.
void checkOutputFile(const std::string& path, const std::vector<std::string>& extensions,
                     const std::string& formats);

/// An output file claimed before any work. The constructor creates its temporary file beside it
/// (PATH.tmp-PID.EXT, same extension, so format-by-extension writers accept it): an output that
/// cannot be created is a UsageError (exit 2) naming PATH before anything is read or computed.
/// commit() writes the temporary through `write(temporary_path)` and renames it onto PATH; a
/// failure leaves neither file, and its message names PATH, never the temporary. The destructor
/// removes the temporary when commit() did not run or failed.
class OutputFile {
 public:
  explicit OutputFile(std::string path);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  const std::string& path() const noexcept { return path_; }
  void commit(const std::function<void(const std::string&)>& write);

 private:
  std::string path_;
  std::string temporary_;
  bool committed_ = false;
};

/// OutputFile(path).commit(write): for an output that needs no claim before the work.
void writeFileAtomically(const std::string& path,
                         const std::function<void(const std::string&)>& write);

/// The Vulkan context, or octovk::Error with the reason there is none.
std::unique_ptr<Context> createContext();

/// readMapFile with OctoMap's reader chatter kept off stderr, capped at `max_device_bytes`
/// (--max-device-memory; 0: no cap); a cap's errors name the option (withOptionNames).
OccupancyMap loadMap(Context& context, const std::string& path, std::size_t max_device_bytes = 0);

/// Points stderr at /dev/null while alive (OctoMap's readers and writers report there).
class StderrSilencer {
 public:
  StderrSilencer();
  ~StderrSilencer();
  StderrSilencer(const StderrSilencer&) = delete;
  StderrSilencer& operator=(const StderrSilencer&) = delete;

 private:
  int saved_ = -1;
};

// ---- TUM RGB-D folders, shared by integrate and convert (convert.cpp) ----

/// The options that take several values, for ArgReader: --intrinsics FX FY CX CY.
std::vector<std::pair<std::string, std::string>> cameraMultiValueOptions();
/// The options that take one value, for ArgReader: --depth-scale.
std::vector<std::string> cameraValueOptions();
/// Applies --intrinsics or --depth-scale to `camera` (UsageError for a bad value); false when
/// `option` is neither.
bool parseCameraOption(const ParsedOption& option, CameraIntrinsics& camera);
/// Checks a TUM RGB-D folder before any work: it exists, is a directory and holds depth.txt and
/// groundtruth.txt. Throws UsageError naming the problem; `usage` is the command's usage line.
void checkTumFolder(const std::string& dir, const std::string& usage);
/// The help text of DIR and of the camera options (for integrate and convert).
void printTumFolderHelp(std::ostream& out);
void printCameraOptionsHelp(std::ostream& out);
/// The summary line of a sequence: images listed, used, skipped for want of a pose.
std::string tumImagesSummary(const TumSequence& sequence);

// ---- the device-memory cap, for the commands that build a map (device_memory.cpp) ----

/// The option that sets MapParams::max_device_bytes.
inline constexpr const char* kMaxDeviceMemoryOption = "--max-device-memory";
/// --max-device-memory's value: bytes, or with K, M, G, T (KiB ... TiB; "512M", "2GiB"); 0 is no
/// cap. A UsageError naming the option otherwise.
std::size_t parseByteCount(const ParsedOption& option);
/// A UsageError when `params.max_device_bytes` is set below what an empty map holds.
void checkDeviceMemoryCap(const MapParams& params);
/// `e` with the library's name for the cap (MapParams::max_device_bytes) in the program's.
Error withOptionNames(const Error& e);
/// The help lines of --max-device-memory; `what_fails` begins the sentence on its error ("A scan").
void printMaxDeviceMemoryHelp(std::ostream& out, const char* what_fails);

/// The log-odds at and above which a node is occupied (OctoMap's occ_prob_thres_log, in float).
float occupancyLogOdds(const MapParams& params);

}  // namespace octovk::cli
