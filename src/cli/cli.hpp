// The octovk program's pieces shared between its commands: usage errors, option values, help.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <memory>
#include <optional>
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

/// Seconds since `start` on the steady clock, for the times the commands report.
using Clock = std::chrono::steady_clock;
inline double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

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

/// A box option's six values XMIN YMIN ZMIN XMAX YMAX ZMAX (--box, --clear-box), each a finite
/// number and min <= max on every axis (a UsageError naming the option otherwise).
std::array<double, 6> parseBox(const ParsedOption& option, const std::string& example);

/// True when `args` asks for help (-h / --help before any "--").
bool wantsHelp(const std::vector<std::string>& args);

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

/// Refuses (UsageError, exit 2) an output that is the same file as an input or as another
/// output, also through a symlink or a hard link, and an existing output that is not a regular
/// file (a pipe or device would be replaced by the rename, not written).
void checkOutputsDistinct(const std::vector<std::string>& outputs,
                          const std::vector<std::string>& inputs);

/// The output files of a run, all or nothing. The constructor checks them (checkOutputsDistinct),
/// removes what killed runs left for them, and creates each one's temporary beside it
/// (DIR/.NAME.octovk.tmp-PID.EXT, same extension, so format-by-extension writers accept it; a
/// NAME too long for that is cut and given a hash, so that every name the directory takes
/// works): an output that cannot be created is a UsageError naming it before anything is read or
/// computed. An output that is a symlink stays one: its target is written (the temporary beside
/// the target). write() fills an output's temporary and syncs it; commit(), once all are written,
/// gives each the permission bits (and, where allowed, the owner) of the file it replaces,
/// renames them into place, and if one rename fails puts every replaced file back. commit() holds
/// an exclusive flock on each output's directory, taken in a fixed order, so that runs writing the
/// same outputs at once take turns and the set is always one run's. Messages name the user's
/// path, never the temporary. Until commit() the destructor and SIGHUP / SIGINT / SIGTERM (see
/// installSignalCleanup) remove the temporaries, so a failed run leaves every file as it was.
class OutputFiles {
 public:
  OutputFiles(const std::vector<std::string>& paths, const std::vector<std::string>& inputs);
  ~OutputFiles();
  OutputFiles(const OutputFiles&) = delete;
  OutputFiles& operator=(const OutputFiles&) = delete;

  std::size_t size() const noexcept { return entries_.size(); }
  const std::string& path(std::size_t index) const { return entries_.at(index).path; }
  /// Writes output `index` through `write(temporary_path)` and syncs it to disk.
  void write(std::size_t index, const std::function<void(const std::string&)>& write);
  /// Renames every output into place; all or none (octovk::Error naming the output that failed).
  void commit();

 private:
  struct Entry {
    std::string path;    // as the user gave it (messages)
    std::string target;  // the file it names, through symlinks (renamed into place)
    std::string ext;     // the extension of `path`, which the temporary keeps
    std::string temporary;
    bool written = false;
  };
  void claim(const std::vector<std::string>& paths);
  void removeTemporaries();
  std::vector<Entry> entries_;
  bool committed_ = false;
};

/// Makes SIGHUP, SIGINT and SIGTERM remove the temporaries of every OutputFiles and then end the
/// process by the signal (exit status 128+N in a shell), and ignores SIGXFSZ, so that a file past
/// `ulimit -f` is a write error (EFBIG) reported and cleaned up as any other. Call first in main(),
/// before any thread.
void installSignalCleanup();

/// Flushes stdout; false when anything written to it was lost (errno says why, or is 0 when an
/// earlier write failed): a closed or full standard output is a failure of the run.
bool flushStdout();

/// Checks that `path` is an existing regular file that can be read, without blocking on a FIFO.
/// Throws UsageError naming `what` ("map file", "scan graph") and the fix.
void checkRegularInput(const std::string& path, const std::string& what, const std::string& fix);

/// The Vulkan context, or octovk::Error with the reason there is none.
std::unique_ptr<Context> createContext();

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
/// The summary's words on a sequence: images listed, used, skipped for want of a pose.
std::string tumImagesText(const TumSequence& sequence);

// ---- the device-memory cap, for the commands that build a map (device_memory.cpp) ----

/// The option that sets MapParams::max_device_bytes.
inline constexpr const char* kMaxDeviceMemoryOption = "--max-device-memory";
/// --max-device-memory's value: bytes, or with K, M, G, T (KiB ... TiB; "512M", "2GiB"); 0 is no
/// cap. A UsageError naming the option otherwise.
std::size_t parseByteCount(const ParsedOption& option);
/// "N bytes (X.Y MiB)", as the cap's messages write a number of bytes.
std::string bytesText(std::size_t bytes);
/// A UsageError when `params.max_device_bytes` is set below what an empty map holds.
void checkDeviceMemoryCap(const MapParams& params);
/// `e` with the library's name for the cap (MapParams::max_device_bytes) in the program's.
Error withOptionNames(const Error& e);
/// The help lines of --max-device-memory; `what_fails` begins the sentence on its error ("A scan").
void printMaxDeviceMemoryHelp(std::ostream& out, const char* what_fails);

/// A box corner clamped into the map's domain (the centres of the cells with keys 0 and 65535,
/// keyToCoord), so that a box larger than the map means all of it rather than nothing
/// (OctoMap's leaf_bbx_iterator visits nothing for a corner outside it).
inline Eigen::Vector3f clampToDomain(double x, double y, double z, double resolution) {
  const Eigen::Vector3f lo = keyToCoord(resolution, Key{0, 0, 0});
  const Eigen::Vector3f hi = keyToCoord(resolution, Key{65535, 65535, 65535});
  const Eigen::Vector3d p(x, y, z);
  Eigen::Vector3f clamped;
  for (int a = 0; a < 3; ++a)
    clamped[a] = static_cast<float>(std::clamp(p[a], double{lo[a]}, double{hi[a]}));
  return clamped;
}

/// The log-odds at and above which a node is occupied (OctoMap's occ_prob_thres_log, in float).
float occupancyLogOdds(const MapParams& params);

/// The map as OctoMap writes it (.bt: writeBinary, pruned max-likelihood; .ot: write), straight
/// into `path` (an output's temporary; integrate.cpp). Returns the nodes the file holds, as
/// OctoMap's size() counts them when it reads the file back (a .bt's after pruning).
std::size_t writeMap(OccupancyMap& map, const std::string& path);

/// writeMap into output `index` of `outputs`; a stamped map's .ot also puts its stamps (which
/// writeMapFile writes beside the file as PATH.stamps) into output `stamps_index`, which the
/// command added as the map's path + ".stamps" (Invocation::addOptionOutput), so that they are
/// renamed with the map, all or nothing. Returns what writeMap returns.
std::size_t writeMapOutput(OccupancyMap& map, OutputFiles& outputs, std::size_t index,
                           std::optional<std::size_t> stamps_index);

}  // namespace octovk::cli
