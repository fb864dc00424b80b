// The height and distance colormaps.
#include "png.hpp"

#include <algorithm>

namespace octovk::cli {

Rgb heightColor(double t) {
  // Google's polynomial fit of Turbo (Mikhailov 2019), over [0.08, 0.92]: its ends are too dark
  // to shade.
  const double x = 0.08 + 0.84 * std::clamp(t, 0.0, 1.0);
  const auto poly = [x](const double(&c)[6]) {
    double sum = 0.0, power = 1.0;
    for (double coefficient : c) {
      sum += coefficient * power;
      power *= x;
    }
    return static_cast<std::uint8_t>(std::clamp(sum, 0.0, 1.0) * 255.0 + 0.5);
  };
  static constexpr double kRed[6] = {0.13572138,   4.61539260,    -42.66032258,
                                     132.13108234, -152.94239396, 59.28637943};
  static constexpr double kGreen[6] = {0.09140261,   2.19418839, 4.84296658,
                                       -14.18503333, 4.27729857, 2.82956604};
  static constexpr double kBlue[6] = {0.10667330,   12.64194608,  -60.58204836,
                                      110.36276771, -89.90310912, 27.34824973};
  return {poly(kRed), poly(kGreen), poly(kBlue)};
}

Rgb distanceColor(double t) { return heightColor(1.0 - std::clamp(t, 0.0, 1.0)); }

}  // namespace octovk::cli
