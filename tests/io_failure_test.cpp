// std::bad_alloc at the file functions' edge: this executable's operator new fails the N-th host
// allocation of the test's own thread (as failure_test.cpp's does), for every N that reading and
// writing a small .bt, .ot and .graph go through. Each call either succeeds or throws an
// octovk::Error with kOutOfHostMemory (never std::bad_alloc); a failed write leaves the file it
// was to replace as it was, and no temporary beside it.
#include <octomap/octomap.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <new>
#include <random>
#include <typeinfo>

#include "host_alloc_hook.hpp"
#include "octovk/tum_sequence.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

namespace fs = std::filesystem;

// Runs `op` with the N-th allocation failing, for N = 1, 2, ... until an attempt allocates fewer
// than N times (it then ran whole). `check(failed)` runs after each attempt, disarmed. Returns
// the attempts that threw (kOutOfHostMemory, as asserted here).
std::uint64_t everyFailure(const std::string& what, const std::function<void()>& op,
                           const std::function<void(bool failed)>& check) {
  std::uint64_t failures = 0;
  for (std::uint64_t n = 1; n < 200000; ++n) {
    SCOPED_TRACE(what + ": allocation " + std::to_string(n) + " fails");
    std::exception_ptr thrown;
    host_count.store(0);
    host_fail_at.store(n);
    host_armed = true;
    try {
      op();
    } catch (...) {
      thrown = std::current_exception();
    }
    host_armed = false;
    const std::uint64_t counted = host_count.load();
    bool failed = false;
    if (thrown) {
      try {
        std::rethrow_exception(thrown);
      } catch (const Error& e) {
        failed = true;
        ++failures;
        EXPECT_EQ(e.code(), ErrorCode::kOutOfHostMemory) << e.what();
      } catch (const std::exception& e) {
        ADD_FAILURE() << "a " << typeid(e).name() << " escaped: " << e.what();
        return failures;
      }
    }
    check(failed);
    if (::testing::Test::HasFailure()) return failures;
    if (!failed && counted < n) return failures;  // ran whole: every allocation was tried
  }
  ADD_FAILURE() << "no end of allocations";
  return failures;
}

// A small map: a few scans at 0.2 m.
OccupancyMap smallMap(Context& ctx) {
  std::mt19937 rng(5);
  OccupancyMap map(ctx, test::withResolution(0.2));
  for (int i = 0; i < 2; ++i) {
    const Eigen::Vector3f origin(0.1f * static_cast<float>(i), 0.0f, 0.0f);
    map.insertPointCloud(test::randomScan(rng, origin, 40, 1.0f), origin);
  }
  return map;
}

bool skipForValidation() {
  // The validation layer allocates on the calling thread inside Vulkan calls, where an exception
  // cannot pass (as in failure_test.cpp).
  const char* v = std::getenv("OCTOVK_VALIDATION");
  return v && *v && std::string(v) != "0";
}

TEST(IoFailure, EveryHostAllocationOfReadingAMapFile) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  if (skipForValidation()) GTEST_SKIP() << "no host failures under the validation layer";
  OccupancyMap map = smallMap(ctx);
  for (const char* ext : {".bt", ".ot"}) {
    const std::string path = test::tmpPath(std::string("alloc_read") + ext);
    writeMapFile(map, path);
    const std::size_t nodes = readMapFile(ctx, path).nodeCount();  // and its passes built
    std::size_t read_nodes = 0;
    const std::uint64_t failures = everyFailure(
        std::string("readMapFile ") + ext, [&] { read_nodes = readMapFile(ctx, path).nodeCount(); },
        [&](bool failed) {
          if (!failed) {
            EXPECT_EQ(read_nodes, nodes);
          }
        });
    std::printf("[ failures ] readMapFile %s: %llu allocation failures threw\n", ext,
                static_cast<unsigned long long>(failures));
    EXPECT_GT(failures, 10u) << ext;
    fs::remove(path);
  }
}

TEST(IoFailure, EveryHostAllocationOfWritingAMapFileLeavesTheOldFile) {
  OCTOVK_REQUIRE_CONTEXT(ctx);
  if (skipForValidation()) GTEST_SKIP() << "no host failures under the validation layer";
  OccupancyMap map = smallMap(ctx);
  const fs::path dir = fs::path(test::tmpPath("alloc_write"));
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const char* ext : {".bt", ".ot"}) {
    const std::string path = (dir / (std::string("map") + ext)).string();
    writeMapFile(map, path);  // its passes built
    const std::string expected = test::fileBytes(path);
    test::writeBytes(path, "old");
    const std::uint64_t failures = everyFailure(
        std::string("writeMapFile ") + ext, [&] { writeMapFile(map, path); },
        [&](bool failed) {
          EXPECT_EQ(test::fileBytes(path), failed ? std::string("old") : expected);
          std::size_t files = 0;
          for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++files;
          EXPECT_EQ(files, 1u) << "a temporary was left beside " << path;
          test::writeBytes(path, "old");  // for the next attempt
        });
    std::printf("[ failures ] writeMapFile %s: %llu allocation failures threw\n", ext,
                static_cast<unsigned long long>(failures));
    EXPECT_GT(failures, 10u) << ext;
    fs::remove(path);
  }
}

TEST(IoFailure, EveryHostAllocationOfAScanGraph) {
  if (skipForValidation()) GTEST_SKIP() << "no host failures under the validation layer";
  std::mt19937 rng(6);
  std::vector<GraphScan> scans(3);
  for (GraphScan& s : scans) {
    s.points_sensor = test::randomScan(rng, Eigen::Vector3f::Zero(), 30, 2.0f);
    s.T_world_sensor.translation = {0.5f, 0.25f, 0.0f};
  }
  const std::string path = test::tmpPath("alloc.graph");
  const auto scan = [&](std::size_t i) { return scans[i]; };
  const std::uint64_t writes = everyFailure(
      "writeScanGraph", [&] { writeScanGraph(path, scans.size(), scan); }, [](bool) {});
  writeScanGraph(path, scans.size(), scan);
  std::vector<GraphScan> read;
  const std::uint64_t reads = everyFailure(
      "readScanGraph", [&] { read = readScanGraph(path); },
      [&](bool failed) {
        if (!failed) {
          ASSERT_EQ(read.size(), scans.size());
          EXPECT_EQ(read[2].points_sensor, scans[2].points_sensor);
        }
      });
  EXPECT_GT(writes, 3u);
  EXPECT_GT(reads, 3u);
  fs::remove(path);
}

TEST(IoFailure, EveryHostAllocationOfReadingATumFolder) {
  if (skipForValidation()) GTEST_SKIP() << "no host failures under the validation layer";
  const fs::path dir = fs::path(test::tmpPath("alloc_tum"));
  fs::remove_all(dir);
  fs::create_directories(dir / "depth");
  test::writeBytes((dir / "groundtruth.txt").string(),
                   "# timestamp tx ty tz qx qy qz qw\n1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n");
  test::writeBytes((dir / "depth.txt").string(), "1.0 depth/a.png\n2.01 depth/b.png\n");
  test::writeBytes((dir / "depth" / "a.png").string(), "");  // checked to exist, not read
  test::writeBytes((dir / "depth" / "b.png").string(), "");
  const std::string folder = dir.string();  // not allocated while armed
  TumSequence read;
  const std::uint64_t failures = everyFailure(
      "readTumSequence", [&] { read = readTumSequence(folder); },
      [&](bool failed) {
        if (!failed) {
          EXPECT_EQ(read.frames.size(), 2u);
        }
      });
  EXPECT_GT(failures, 10u);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace octovk
