// The octovk program's pieces shared between its commands: usage errors, option values, help.
#pragma once

#include <cstddef>
#include <iosfwd>
#include <stdexcept>
#include <string>
#include <vector>

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
  std::string value;  ///< empty for flags
};

/// Walks `args` and splits them into options and positional arguments. `takes_value` says which
/// option names consume a value; names not listed are flags. Unknown names are kept for the
/// caller to reject with its own list. "--" ends the options.
class ArgReader {
 public:
  ArgReader(const std::vector<std::string>& args, std::vector<std::string> value_options);

  /// The next option or positional argument; false at the end.
  bool next();
  bool isOption() const noexcept { return is_option_; }
  const ParsedOption& option() const noexcept { return option_; }
  const std::string& positional() const noexcept { return positional_; }

 private:
  const std::vector<std::string>& args_;
  std::vector<std::string> value_options_;
  std::size_t at_ = 0;
  bool options_done_ = false;
  bool is_option_ = false;
  ParsedOption option_;
  std::string positional_;
};

/// `text` as a finite double, or a UsageError that names the option and gives `example`.
double parseNumber(const ParsedOption& option, const std::string& example);

/// True when `args` asks for help (-h / --help before any "--").
bool wantsHelp(const std::vector<std::string>& args);

/// The help of `octovk integrate`: usage, every option with its default, files, exit codes.
void printIntegrateHelp(std::ostream& out);
/// `octovk integrate ARGS...` (without the command name). Throws UsageError or octovk::Error.
int runIntegrate(const std::vector<std::string>& args);

/// The environment and exit-code sections every help text ends with.
void printEnvironmentAndExitCodes(std::ostream& out);

}  // namespace octovk::cli
