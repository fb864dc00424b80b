// 8-bit RGB pictures for the octovk commands and their colormaps for heights and distances
// (picture.hpp draws around them and writes them as PNG).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace octovk::cli {

using Rgb = std::array<std::uint8_t, 3>;

/// A picture, rows top to bottom, 3 bytes (red, green, blue) a pixel.
struct RgbImage {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::vector<std::uint8_t> pixels;

  RgbImage(std::uint32_t w, std::uint32_t h)
      : width(w), height(h), pixels(std::size_t{w} * h * 3, 0) {}
  void set(std::uint32_t x, std::uint32_t y, const Rgb& c) {
    const std::size_t at = (std::size_t{y} * width + x) * 3;
    pixels[at] = c[0];
    pixels[at + 1] = c[1];
    pixels[at + 2] = c[2];
  }
};

/// Colour of a height: t = 0 (lowest) … 1 (highest) through a rainbow (Turbo) that stays light
/// enough at both ends to show shading; t is clamped.
Rgb heightColor(double t);

/// Colour of a distance to the nearest obstacle: t = 0 (at an obstacle) … 1 (the maximum
/// distance or farther) through the same scale reversed: red near, blue far; t is clamped.
Rgb distanceColor(double t);

}  // namespace octovk::cli
