// The program on input files that claim far more than they hold: sparse .bt, .ot and .graph files
// of gigabytes (a few kB on disk), read by `info` and `integrate`. Each is one clean error line,
// in little time and memory, also under `ulimit -v` smaller than the file.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cli_support.hpp"
#include "test_support.hpp"

namespace octovk {
namespace {

namespace fs = std::filesystem;
using test::Scratch;

void writeSparse(const std::string& path, const std::string& prefix, std::uintmax_t size) {
  std::ofstream(path, std::ios_base::binary | std::ios_base::trunc) << prefix;
  fs::resize_file(path, size);
}

TEST(CliInput, SparseFilesAreACheapCleanError) {
  // A 3 GiB sparse .bt took `info` 17 s and 3.2 GB of RSS (a .graph `integrate` 12.5 s and
  // 3.1 GB), and one of 10 GiB under `ulimit -v 4G` ended in "unexpected failure:
  // std::bad_alloc". Now the readers read as their checks go, and the zeros fail at once.
  OCTOVK_REQUIRE_CONTEXT(ctx);
  (void)ctx;
  Scratch scratch("cli_input");
  const std::uint32_t one_scan = 1;
  struct Case {
    const char* name;
    std::string prefix;
    std::vector<std::string> args;  // after the program, before the file
    std::vector<std::string> tail;  // after the file
    const char* why;
  };
  const std::vector<Case> cases = {
      {"header.bt",
       "# Octomap OcTree binary file\nid OcTree\nsize 1000\nres 0.1\ndata\n",
       {"info"},
       {},
       "bytes follow the tree's last node record"},
      {"zeros.ot", "", {"info"}, {}, "its first line is"},
      {"one_scan.graph",
       std::string(reinterpret_cast<const char*>(&one_scan), 4),
       {"integrate"},
       {"-o", scratch / "map.bt"},
       "bad scan 0 pose translation record"},
  };
  for (const Case& c : cases) {
    for (const bool limited : {false, true}) {
      SCOPED_TRACE(std::string(c.name) + (limited ? ", 10 GiB under ulimit -v 4G" : ", 3 GiB"));
      const std::string path = scratch / c.name;
      writeSparse(path, c.prefix, (limited ? std::uintmax_t{10} : 3) << 30);
      std::vector<std::string> words = c.args;
      words.push_back(path);
      words.insert(words.end(), c.tail.begin(), c.tail.end());
      const test::RunResult m =
          test::runMeasured(words, scratch.dir(), limited ? "ulimit -v 4194304;" : "");
      test::expectOneErrorLine(m, 1, {c.why, c.name});
      EXPECT_LT(m.max_rss_kb, 300 * 1024) << "peak RSS of the run";
      EXPECT_LT(m.cpu_s, 3.0) << "CPU time of the run";
      EXPECT_FALSE(fs::exists(scratch / "map.bt"));
      fs::remove(path);
    }
  }
}

}  // namespace
}  // namespace octovk
