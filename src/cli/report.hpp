// The summary every octovk command prints on stdout once its work is done, and the named steps
// of a run whose times it reports: one builder, so that every command lines up its values, names
// its times and ends with the files it wrote the same way.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "cli.hpp"

namespace octovk::cli {

/// The named steps of a run and the seconds each took ("reading and upload", "writing"), in the
/// order they first ran; a step run again adds to its time (render's tiles).
class Steps {
 public:
  /// Runs `step()`, adds its time to the step `name` and returns what it returned. A step that
  /// throws adds nothing: the run fails and reports no times.
  template <class F>
  auto run(std::string_view name, F&& step) {
    const auto start = Clock::now();
    if constexpr (std::is_void_v<std::invoke_result_t<F>>) {
      std::forward<F>(step)();
      add(name, secondsSince(start));
    } else {
      auto result = std::forward<F>(step)();
      add(name, secondsSince(start));
      return result;
    }
  }
  /// Adds `seconds` to the step `name` (a new step at the end when there is none by that name).
  void add(std::string_view name, double seconds);
  /// Words after the step's time in the report, e.g. "device 1.234 ms".
  void note(std::string_view name, std::string note);
  /// The seconds of all steps together.
  double total() const;
  /// "0.123 s (reading and upload 0.100 s, writing 0.023 s)", as the time lines print it.
  std::string text() const;

 private:
  struct Step {
    std::string name;
    double seconds = 0.0;
    std::string note;
  };
  Step& find(std::string_view name);
  std::vector<Step> steps_;
};

/// printf into a std::string (the report's numbers).
std::string format(const char* format, ...) __attribute__((format(printf, 1, 2)));

/// "min (X, Y, Z) max (X, Y, Z)" of a box given as XMIN YMIN ZMIN XMAX YMAX ZMAX.
std::string boxText(const std::array<double, 6>& box);

/// A command's summary: "label:" lines whose values start in one column, printed at once by
/// print() (a run that fails prints none of it: its error is the one line it writes).
class Report {
 public:
  /// `column`: where the values start, past the longest label and a space ("device:  ": 9).
  explicit Report(std::size_t column) : column_(column) {}
  /// "label: text" (the label without its colon).
  Report& line(std::string_view label, std::string_view text);
  /// "device: NAME (TYPE)" of the context's device.
  Report& device(Context& context);
  /// "time: T s (step t s, ...)".
  Report& time(const Steps& steps);
  /// "wrote: PATH", one line per path.
  Report& wrote(const std::vector<std::string>& paths);
  Report& wrote(const std::string& path) { return wrote(std::vector<std::string>{path}); }
  /// Writes the summary to stdout and flushes it; returns kExitOk, the run's exit code.
  int print() const;
  /// How a command's summary ends: its times and the files it wrote, then print().
  int finish(const Steps& steps, const std::vector<std::string>& paths = {}) {
    return time(steps).wrote(paths).print();
  }

 private:
  std::size_t column_;
  std::string text_;
};

}  // namespace octovk::cli
