// The program on input files that claim far more than they hold: sparse .bt, .ot and .graph files
// of gigabytes (a few kB on disk), read by `info` and `integrate`. Each is one clean error line,
// in little time and memory, also under `ulimit -v` smaller than the file.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
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
using test::quote;
using test::readFile;
using test::Scratch;

struct Measured {
  int exit_code = -1;
  std::string err;
  long max_rss_kb = 0;
  double cpu_s = 0.0;
};

// `command` run by /bin/sh (which execs the program), with stdout and stderr in files under
// `dir`; wait4() gives that child's own peak RSS and CPU time.
Measured runMeasured(const std::string& command, const fs::path& dir) {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string line = command + " >" + quote(out.string()) + " 2>" + quote(err.string());
  Measured m;
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::execl("/bin/sh", "sh", "-c", line.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  if (pid < 0) {
    ADD_FAILURE() << "fork failed";
    return m;
  }
  int status = 0;
  rusage usage{};
  if (::wait4(pid, &status, 0, &usage) != pid) ADD_FAILURE() << "wait4 failed";
  m.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  m.err = readFile(err);
  m.max_rss_kb = usage.ru_maxrss;
  m.cpu_s = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
            static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) * 1e-6;
  fs::remove(out);
  fs::remove(err);
  return m;
}

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
      {"header.bt", "# Octomap OcTree binary file\nid OcTree\nsize 1000\nres 0.1\ndata\n",
       {"info"}, {}, "bytes follow the tree's last node record"},
      {"zeros.ot", "", {"info"}, {}, "its first line is"},
      {"one_scan.graph", std::string(reinterpret_cast<const char*>(&one_scan), 4),
       {"integrate"}, {"-o", scratch / "map.bt"}, "bad scan 0 pose translation record"},
  };
  for (const Case& c : cases) {
    for (const bool limited : {false, true}) {
      SCOPED_TRACE(std::string(c.name) + (limited ? ", 10 GiB under ulimit -v 4G" : ", 3 GiB"));
      const std::string path = scratch / c.name;
      writeSparse(path, c.prefix, (limited ? std::uintmax_t{10} : 3) << 30);
      std::string command = limited ? "ulimit -v 4194304; exec " : "exec ";
      command += quote(OCTOVK_PATH(OCTOVK_CLI));
      std::vector<std::string> words = c.args;
      words.push_back(path);
      words.insert(words.end(), c.tail.begin(), c.tail.end());
      for (const std::string& word : words) command.append(1, ' ').append(quote(word));
      const Measured m = runMeasured(command, scratch.dir());
      EXPECT_EQ(m.exit_code, 1) << m.err;
      EXPECT_EQ(m.err.rfind("octovk: error: ", 0), 0u) << m.err;
      EXPECT_EQ(std::count(m.err.begin(), m.err.end(), '\n'), 1) << m.err;
      EXPECT_NE(m.err.find(c.why), std::string::npos) << m.err;
      EXPECT_NE(m.err.find(c.name), std::string::npos) << m.err;
      EXPECT_LT(m.max_rss_kb, 300 * 1024) << "peak RSS of the run";
      EXPECT_LT(m.cpu_s, 3.0) << "CPU time of the run";
      EXPECT_FALSE(fs::exists(scratch / "map.bt"));
      fs::remove(path);
    }
  }
}

}  // namespace
}  // namespace octovk
