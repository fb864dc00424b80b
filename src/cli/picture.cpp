// The commands' pictures drawn with cairo (picture.hpp): cairo places the text and lines and
// writes the PNG; the pixels the commands computed are pasted in untouched.
#include "picture.hpp"

#include <cairo.h>
#include <fontconfig/fontconfig.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "octovk/octovk.hpp"

namespace octovk::cli {

namespace {

void setColour(cairo_t* cr, const Rgb& c) {
  cairo_set_source_rgb(cr, c[0] / 255.0, c[1] / 255.0, c[2] / 255.0);
}

// Where cairo's PNG writer sends its bytes: a file, with the first error's errno kept.
struct PngSink {
  std::FILE* file = nullptr;
  int error = 0;
};

cairo_status_t writeBytes(void* closure, const unsigned char* data, unsigned int length) {
  auto* sink = static_cast<PngSink*>(closure);
  if (std::fwrite(data, 1, length, sink->file) != length) {
    if (sink->error == 0) sink->error = errno != 0 ? errno : EIO;
    return CAIRO_STATUS_WRITE_ERROR;
  }
  return CAIRO_STATUS_SUCCESS;
}

}  // namespace

namespace {
int live_canvases = 0;
}  // namespace

Canvas::Canvas(std::uint32_t width, std::uint32_t height, const Rgb& background)
    : width_(width), height_(height) {
  surface_ = cairo_image_surface_create(CAIRO_FORMAT_RGB24, static_cast<int>(width),
                                        static_cast<int>(height));
  cr_ = cairo_create(surface_);
  if (cairo_status(cr_) != CAIRO_STATUS_SUCCESS) {
    const std::string why = cairo_status_to_string(cairo_status(cr_));
    cairo_destroy(cr_);
    cairo_surface_destroy(surface_);
    throw Error(ErrorCode::kOutOfHostMemory, "cannot make a " + std::to_string(width) + " x " +
                                                 std::to_string(height) + " picture: " + why);
  }
  ++live_canvases;
  cairo_select_font_face(cr_, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  fill(0, 0, width, height, background);
}

Canvas::~Canvas() {
  cairo_destroy(cr_);
  cairo_surface_destroy(surface_);
  // cairo and fontconfig keep fonts and their configuration for the process, some of it where
  // LeakSanitizer counts it as lost (scripts/sanitize.sh): with the last canvas gone, both give
  // it back (and load it again if another canvas draws text).
  if (--live_canvases == 0) {
    cairo_debug_reset_static_data();
    FcFini();
  }
}

void Canvas::paste(const RgbImage& image, std::uint32_t x, std::uint32_t y) {
  cairo_surface_flush(surface_);
  unsigned char* data = cairo_image_surface_get_data(surface_);
  const int stride = cairo_image_surface_get_stride(surface_);
  const std::uint32_t w = std::min(image.width, width_ > x ? width_ - x : 0);
  const std::uint32_t h = std::min(image.height, height_ > y ? height_ - y : 0);
  for (std::uint32_t r = 0; r < h; ++r) {
    auto* row = reinterpret_cast<std::uint32_t*>(data + std::ptrdiff_t{stride} * (y + r));
    const std::uint8_t* from = image.pixels.data() + std::size_t{r} * image.width * 3;
    for (std::uint32_t c = 0; c < w; ++c, from += 3)
      row[x + c] = std::uint32_t{from[0]} << 16 | std::uint32_t{from[1]} << 8 | from[2];
  }
  cairo_surface_mark_dirty(surface_);
}

void Canvas::fill(double x, double y, double w, double h, const Rgb& colour) {
  setColour(cr_, colour);
  cairo_rectangle(cr_, x, y, w, h);
  cairo_fill(cr_);
}

void Canvas::line(double x0, double y0, double x1, double y1, const Rgb& colour, double width) {
  setColour(cr_, colour);
  cairo_set_line_width(cr_, width);
  cairo_set_line_cap(cr_, CAIRO_LINE_CAP_BUTT);
  cairo_move_to(cr_, x0, y0);
  cairo_line_to(cr_, x1, y1);
  cairo_stroke(cr_);
}

double Canvas::textWidth(const std::string& text, double size) {
  cairo_set_font_size(cr_, size);
  cairo_text_extents_t extents;
  cairo_text_extents(cr_, text.c_str(), &extents);
  return extents.x_advance;
}

void Canvas::text(const std::string& text, double x, double y, double size, const Rgb& colour,
                  Align align) {
  cairo_set_font_size(cr_, size);
  cairo_font_extents_t font;
  cairo_font_extents(cr_, &font);
  const double w = textWidth(text, size);
  const double left = align == Align::kStart ? x : align == Align::kCentre ? x - 0.5 * w : x - w;
  // The baseline that puts the middle of the font's ascent and descent at y.
  cairo_move_to(cr_, left, y + 0.5 * (font.ascent - font.descent));
  setColour(cr_, colour);
  cairo_show_text(cr_, text.c_str());
}

void Canvas::writePng(const std::string& path) {
  cairo_surface_flush(surface_);
  PngSink sink;
  sink.file = std::fopen(path.c_str(), "wb");
  if (sink.file == nullptr)
    throw Error(ErrorCode::kIo, "cannot write PNG '" + path + "': " + std::strerror(errno));
  const cairo_status_t status = cairo_surface_write_to_png_stream(surface_, writeBytes, &sink);
  const bool closed = std::fclose(sink.file) == 0;
  if (sink.error == 0 && !closed) sink.error = errno != 0 ? errno : EIO;
  if (sink.error != 0)
    throw Error(ErrorCode::kIo, "cannot write PNG '" + path + "': " + std::strerror(sink.error));
  if (status != CAIRO_STATUS_SUCCESS)
    throw Error(ErrorCode::kIo,
                "cannot write PNG '" + path + "': " + cairo_status_to_string(status));
}

std::vector<double> niceTicks(double lo, double hi, int most, double* step_out) {
  // Ends computed in float (cell centres) miss a round value by a few ulps: still a tick.
  constexpr double kSlack = 1e-5;
  std::vector<double> ticks;
  if (!(hi >= lo) || !std::isfinite(lo) || !std::isfinite(hi) || most < 1) return ticks;
  if (hi - lo <= 0.0) {
    if (step_out) *step_out = 1.0;
    return {lo};
  }
  // From a round step that gives too many ticks up through the round steps (1, 2, 5, 10, ...)
  // until they fit.
  const auto count = [&](double s) {
    return std::floor(hi / s + kSlack) - std::ceil(lo / s - kSlack) + 1;
  };
  double step = roundLength((hi - lo) / most);
  while (count(step) > most) {
    const double power = std::pow(10.0, std::floor(std::log10(step) + 1e-9));
    const double mantissa = std::round(step / power);
    step = (mantissa < 2 ? 2 : mantissa < 5 ? 5 : 10) * power;
  }
  const double first = std::ceil(lo / step - kSlack) * step;
  for (double v = first; v <= hi + step * kSlack;
       v = first + step * static_cast<double>(ticks.size()))
    ticks.push_back(std::abs(v) < step * kSlack ? 0.0 : v);
  if (step_out) *step_out = step;
  return ticks;
}

std::string tickText(double value, double step, const char* unit) {
  const int decimals = std::clamp(static_cast<int>(std::ceil(-std::log10(step) - 1e-9)), 0, 6);
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", decimals, value);
  std::string out = text;
  if (out == "-0" || out.rfind("-0.", 0) == 0) {
    // "-0.00" for a value that rounds to zero: plain zero.
    if (std::abs(value) < 0.5 * std::pow(10.0, -decimals)) out = out.substr(1);
  }
  if (unit[0] != '\0') out += std::string(" ") + unit;
  return out;
}

double roundLength(double most_m) {
  if (!(most_m > 0.0) || !std::isfinite(most_m)) return 1.0;
  const double power = std::pow(10.0, std::floor(std::log10(most_m)));
  for (const double m : {5.0, 2.0, 1.0})
    if (m * power <= most_m * (1 + 1e-9)) return m * power;
  return power;
}

}  // namespace octovk::cli
