// Helpers of the tests that run the `octovk` program: shell quoting, running it with its output
// captured, and a scratch directory per test.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace octovk::test {

namespace fs = std::filesystem;

inline std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

inline std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios_base::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

/// Runs `command` through the shell with stdout and stderr captured in files under `dir`.
inline RunResult runShell(const std::string& command, const fs::path& dir) {
  const fs::path out = dir / "stdout.txt";
  const fs::path err = dir / "stderr.txt";
  const int status =
      std::system((command + " >" + quote(out) + " 2>" + quote(err) + " </dev/null").c_str());
  RunResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = readFile(out);
  r.err = readFile(err);
  fs::remove(out);
  fs::remove(err);
  return r;
}

/// Runs the built octovk program with `args`.
inline RunResult runOctovk(const std::vector<std::string>& args, const fs::path& dir) {
  std::string command = quote(OCTOVK_CLI);
  for (const std::string& a : args) command += ' ' + quote(a);
  return runShell(command, dir);
}

/// A fresh directory per test under OCTOVK_TEST_TMP, removed when the test passed.
class Scratch {
 public:
  explicit Scratch(const std::string& prefix = "cli") {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = prefix + "." + std::string(info->test_suite_name()) + "." + info->name() +
                       "." + std::to_string(::getpid());
    std::replace(name.begin(), name.end(), '/', '_');  // parameterized names hold slashes
    dir_ = fs::path(OCTOVK_TEST_TMP) / name;
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~Scratch() {
    if (!::testing::Test::HasFailure()) fs::remove_all(dir_);
  }
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  const fs::path& dir() const { return dir_; }
  std::string operator/(const std::string& name) const { return (dir_ / name).string(); }

 private:
  fs::path dir_;
};

}  // namespace octovk::test
