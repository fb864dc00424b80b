// Command-line parsing shared by the octovk commands.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <ostream>

#include "cli.hpp"

namespace octovk::cli {

ArgReader::ArgReader(const std::vector<std::string>& args, std::vector<std::string> value_options)
    : args_(args), value_options_(std::move(value_options)) {}

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
  return true;
}

double parseNumber(const ParsedOption& option, const std::string& example) {
  const std::string& text = option.value;
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  const bool whole = !text.empty() && end == text.c_str() + text.size();
  if (!whole || errno == ERANGE || !std::isfinite(value))
    throw UsageError(option.name + " expects a number, got '" + text + "'; e.g. " + option.name +
                     " " + example);
  return value;
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
         "\n"
         "Exit codes:\n"
         "  0  success\n"
         "  1  failure while working: corrupt or truncated input, Vulkan or device error,\n"
         "     a file could not be written; no output file is left behind\n"
         "  2  usage error: unknown command or option, missing or bad value, missing input,\n"
         "     output in a directory that does not exist or cannot be written; nothing is done\n"
         "Errors are one line on stderr starting with 'octovk: error: '.\n";
}

}  // namespace octovk::cli
