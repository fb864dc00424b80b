// The summary lines and step times of the octovk commands (report.hpp).
#include "report.hpp"

#include <cstdarg>
#include <cstdio>
#include <iostream>
#include <numeric>

namespace octovk::cli {

Steps::Step& Steps::find(std::string_view name) {
  for (Step& step : steps_)
    if (step.name == name) return step;
  return steps_.emplace_back(Step{std::string(name)});
}

void Steps::add(std::string_view name, double seconds) { find(name).seconds += seconds; }

void Steps::note(std::string_view name, std::string note) { find(name).note = std::move(note); }

double Steps::total() const {
  return std::accumulate(steps_.begin(), steps_.end(), 0.0,
                         [](double sum, const Step& step) { return sum + step.seconds; });
}

std::string Steps::text() const {
  std::string text = format("%.3f s (", total());
  for (std::size_t i = 0; i < steps_.size(); ++i) {
    const Step& step = steps_[i];
    text += (i == 0 ? "" : ", ") + step.name + format(" %.3f s", step.seconds);
    if (!step.note.empty()) text += " (" + step.note + ")";
  }
  return text + ")";
}

std::string format(const char* format, ...) {
  std::va_list args;
  va_start(args, format);
  std::va_list again;
  va_copy(again, args);
  const int size = std::vsnprintf(nullptr, 0, format, args);
  va_end(args);
  std::string text(size > 0 ? static_cast<std::size_t>(size) : 0, '\0');
  if (size > 0) std::vsnprintf(text.data(), text.size() + 1, format, again);
  va_end(again);
  return text;
}

std::string boxText(const std::array<double, 6>& b) {
  return format("min (%g, %g, %g) max (%g, %g, %g)", b[0], b[1], b[2], b[3], b[4], b[5]);
}

Report& Report::line(std::string_view label, std::string_view text) {
  std::string head = std::string(label) + ":";
  head.resize(std::max(head.size() + 1, column_), ' ');
  text_ += head;
  text_ += text;
  text_ += '\n';
  return *this;
}

Report& Report::device(Context& context) {
  return line("device", context.device().name + " (" + context.device().type + ")");
}

Report& Report::time(const Steps& steps) { return line("time", steps.text()); }

Report& Report::wrote(const std::vector<std::string>& paths) {
  for (const std::string& path : paths) line("wrote", path);
  return *this;
}

int Report::print() const {
  std::cout << text_ << std::flush;
  return kExitOk;
}

}  // namespace octovk::cli
