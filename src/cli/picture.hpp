// Pictures that carry their numbers: a canvas (cairo) on which the commands paste what they
// computed pixel for pixel, then draw text, lines and legends around it, and which cairo writes
// as an 8-bit RGB PNG.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "png.hpp"

typedef struct _cairo cairo_t;
typedef struct _cairo_surface cairo_surface_t;

namespace octovk::cli {

/// A picture to draw on: `width` x `height` pixels of `background`.
class Canvas {
 public:
  enum class Align { kStart, kCentre, kEnd };

  Canvas(std::uint32_t width, std::uint32_t height, const Rgb& background);
  ~Canvas();
  Canvas(const Canvas&) = delete;
  Canvas& operator=(const Canvas&) = delete;

  std::uint32_t width() const noexcept { return width_; }
  std::uint32_t height() const noexcept { return height_; }

  /// Copies `image` with its top-left corner at pixel (x, y), pixel for pixel.
  void paste(const RgbImage& image, std::uint32_t x, std::uint32_t y);
  /// A filled rectangle (pixel edges at whole numbers: no blending at its border).
  void fill(double x, double y, double w, double h, const Rgb& colour);
  /// A straight line `width` pixels wide (ends cut square).
  void line(double x0, double y0, double x1, double y1, const Rgb& colour, double width = 1.0);
  /// Text `size` pixels high: `x` is its left edge, centre or right edge (`align`), `y` its
  /// vertical centre.
  void text(const std::string& text, double x, double y, double size, const Rgb& colour,
            Align align = Align::kStart);
  /// How wide `text` is at `size` pixels.
  double textWidth(const std::string& text, double size);
  /// Writes the canvas to `path` as an 8-bit RGB PNG. Throws octovk::Error (kIo) with the reason.
  void writePng(const std::string& path);

 private:
  std::uint32_t width_, height_;
  cairo_surface_t* surface_ = nullptr;
  cairo_t* cr_ = nullptr;
};

/// Round values (1, 2 or 5 times a power of ten apart) from `lo` to `hi`, at most `most` and at
/// least two where the range allows; their step in `step`.
std::vector<double> niceTicks(double lo, double hi, int most, double* step = nullptr);

/// `value` with the decimals a tick `step` needs ("0.5", "12", "-0.25"), and a unit after it
/// when `unit` is not empty ("0.5 m").
std::string tickText(double value, double step, const char* unit = "");

/// The longest round length (1, 2 or 5 times a power of ten) at most `most_m` metres.
double roundLength(double most_m);

}  // namespace octovk::cli
