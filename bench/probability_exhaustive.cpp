// integrateNodeColor's weight over every float of OctoMap's default clamping range: the device's
// occupancyProbability (shaders/probability.glsl) against OctoMap's getOccupancy() (glibc's exp)
// for each of the about 2.15 billion log-odds in [-2.000028, 3.5110307], bit for bit. Where they
// differ, libquadmath's expq says whether the device's p is the one a correctly rounded exp gives
// (glibc's exp, about 0.51 ULP, is not always correctly rounded), and every pair of channel values
// (old, new) is folded with both p to count the colours that would differ. Run once, not in CI
// (minutes on lavapipe); docs/benchmarks.md has the command and the result.
//   octovk_probability_exhaustive [lo hi]   (default: the default clamping range's log-odds)
#include <octomap/ColorOcTree.h>
#include <quadmath.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "map/context_access.hpp"
#include "map/device_probe.hpp"
#include "octovk/octovk.hpp"
#include "probability_oracle.hpp"

namespace {

using octovk::test::floatOfOrdinal;
using octovk::test::integratedChannel;
using octovk::test::ordinalOf;

std::uint64_t bitsOf(double d) { return std::bit_cast<std::uint64_t>(d); }

}  // namespace

int main(int argc, char** argv) {
  octomap::ColorOcTree tree(0.1);  // OctoMap's default clamping: 0.1192 .. 0.971
  float lo = tree.getClampingThresMinLog(), hi = tree.getClampingThresMaxLog();
  if (argc == 3) {
    lo = std::strtof(argv[1], nullptr);
    hi = std::strtof(argv[2], nullptr);
  }
  auto context = octovk::Context::create();
  if (!context) {
    std::fprintf(stderr, "no device: %s\n", context.error().what());
    return 1;
  }
  octovk::vk::Device& device = octovk::ContextAccess::device(*context.value());
  std::printf("device: %s\nlog-odds %a .. %a (%.9g .. %.9g)\n",
              context.value()->device().name.c_str(), static_cast<double>(lo),
              static_cast<double>(hi), static_cast<double>(lo), static_cast<double>(hi));
  const auto start = std::chrono::steady_clock::now();
  const std::int64_t first = ordinalOf(lo), last = ordinalOf(hi);
  constexpr std::int64_t kChunk = std::int64_t{1} << 24;
  std::vector<float> values;
  std::uint64_t total = 0, differ = 0, not_correctly_rounded = 0, glibc_correct = 0,
                colour_pairs = 0, colour_values = 0;
  static std::uint64_t pair_count[256][256];  // log-odds at which (old, new) folds differently
  std::uint64_t lower = 0;                    // pairs where the device's byte is the lower
  octomap::ColorOcTreeNode node;
  for (std::int64_t o = first; o <= last; o += kChunk) {
    values.clear();
    for (std::int64_t k = o; k <= std::min(last, o + kChunk - 1); ++k)
      values.push_back(floatOfOrdinal(k));
    const std::vector<double> got = octovk::deviceOccupancies(device, values);
    for (std::size_t i = 0; i < values.size(); ++i) {
      node.setLogOdds(values[i]);
      const double octomap_p = node.getOccupancy();
      ++total;
      if (bitsOf(octomap_p) == bitsOf(got[i])) continue;
      ++differ;
      const double x = static_cast<double>(values[i]);
      const double exact_exp = static_cast<double>(expq(static_cast<__float128>(x)));
      const double exact_p = 1. - (1. / (1. + exact_exp));
      if (bitsOf(exact_p) != bitsOf(got[i])) {
        if (++not_correctly_rounded <= 10)
          std::printf(
              "device's p is not the correctly rounded exp's: log-odds %a: device %a, "
              "correctly rounded %a, OctoMap %a\n",
              x, got[i], exact_p, octomap_p);
      }
      glibc_correct += bitsOf(std::exp(x)) == bitsOf(exact_exp);
      std::uint64_t pairs = 0;
      for (int old = 0; old < 256; ++old)
        for (int c = 0; c < 256; ++c) {
          const std::uint8_t want = integratedChannel(old, c, octomap_p);
          const std::uint8_t mine = integratedChannel(old, c, got[i]);
          if (want == mine) continue;
          ++pair_count[old][c];
          lower += mine < want;
          if (++pairs == 1 && colour_values < 5)
            std::printf("log-odds %a (%.9g), old %d, new %d: OctoMap %d (p %a), device %d (p %a)\n",
                        x, x, old, c, want, octomap_p, mine, got[i]);
        }
      colour_pairs += pairs;
      colour_values += pairs != 0;
    }
    std::fprintf(
        stderr, "\r%.1f %%",
        100.0 * static_cast<double>(o + kChunk - first) / static_cast<double>(last - first + 1));
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "\n%llu log-odds in %.0f s\n"
      "p differs from OctoMap's getOccupancy(): %llu\n"
      "  of which the device's p is not the correctly rounded exp's: %llu\n"
      "  of which glibc's exp is correctly rounded: %llu\n"
      "  of which some (old, new) channel pair folds to another colour: %llu (%llu pairs)\n",
      static_cast<unsigned long long>(total), seconds, static_cast<unsigned long long>(differ),
      static_cast<unsigned long long>(not_correctly_rounded),
      static_cast<unsigned long long>(glibc_correct),
      static_cast<unsigned long long>(colour_values),
      static_cast<unsigned long long>(colour_pairs));
  for (int old = 0; old < 256; ++old)
    for (int c = 0; c < 256; ++c)
      if (pair_count[old][c])
        std::printf("    (old %d, new %d) at %llu log-odds\n", old, c,
                    static_cast<unsigned long long>(pair_count[old][c]));
  std::printf("    the device's byte the lower in %llu pairs\n",
              static_cast<unsigned long long>(lower));
  return not_correctly_rounded == 0 && glibc_correct == 0 ? 0 : 1;
}
