// Helpers of the tests that run the `octovk` program: shell quoting, running it with its output
// captured, and a scratch directory per test.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "test_paths.hpp"

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
  long max_rss_kb = -1;  ///< the run's peak resident memory (runMeasured only)
  double cpu_s = -1.0;   ///< the run's user and system CPU time (runMeasured only)
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
  std::string command = quote(OCTOVK_PATH(OCTOVK_CLI));
  for (const std::string& a : args) command += ' ' + quote(a);
  return runShell(command, dir);
}

/// Runs octovk with `args` as runOctovk does, after `shell_prefix` (e.g. "ulimit -v 4194304;"),
/// and measures that program alone: its peak RSS and CPU time. wait4() on a child of this test
/// process cannot: Linux carries the larger of the parent's and the child's peak through fork and
/// exec, so every child of a test process holding a GPU driver (NVIDIA's: over 100 MiB) "peaked"
/// there. The program runs as the grandchild of a small python3 (whose own peak, about 10 MiB, is
/// the floor), which writes RUSAGE_CHILDREN to a file and exits with the program's status.
inline RunResult runMeasured(const std::vector<std::string>& args, const fs::path& dir,
                             const std::string& shell_prefix = "") {
  const fs::path usage = dir / "usage.txt";
  std::string command = shell_prefix + " exec python3 -c " +
                        quote(
                            "import resource, subprocess, sys\n"
                            "code = subprocess.run(sys.argv[2:]).returncode\n"
                            "u = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
                            "open(sys.argv[1], 'w').write('%d %.6f' % (u.ru_maxrss, "
                            "u.ru_utime + u.ru_stime))\n"
                            "sys.exit(code if code >= 0 else 128 - code)\n") +
                        ' ' + quote(usage.string()) + ' ' + quote(OCTOVK_PATH(OCTOVK_CLI));
  for (const std::string& a : args) command += ' ' + quote(a);
  RunResult r = runShell(command, dir);
  std::ifstream in(usage);
  if (!(in >> r.max_rss_kb >> r.cpu_s))
    ADD_FAILURE() << "no usage written by the measuring python3 (exit " << r.exit_code
                  << "): " << r.err;
  fs::remove(usage);
  return r;
}

/// The run ended with `exit_code` and one stderr line "octovk: error: ..." naming each of
/// `mentions`.
inline void expectOneErrorLine(const RunResult& r, int exit_code,
                               const std::vector<std::string>& mentions) {
  EXPECT_EQ(r.exit_code, exit_code) << r.err;
  EXPECT_EQ(r.err.rfind("octovk: error: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  for (const std::string& mention : mentions)
    EXPECT_NE(r.err.find(mention), std::string::npos)
        << "expected '" << mention << "' in: " << r.err;
}

/// The names in `dir` that only a fault leaves: octovk's temporaries and backups
/// (".NAME.octovk.tmp-PID.EXT", ".NAME.octovk.tmp-PID.old") and any other "*.tmp*" file.
inline std::vector<std::string> temporariesIn(const fs::path& dir) {
  std::vector<std::string> found;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.find(".tmp") != std::string::npos) found.push_back(name);
  }
  std::sort(found.begin(), found.end());
  return found;
}

/// The built octovk program started with `args` and left running, to be signalled: stdout and
/// stderr go to files in `dir`, every signal has its default action and none is blocked (as from
/// an interactive shell, whatever the test process inherited).
class OctovkProcess {
 public:
  OctovkProcess(const std::vector<std::string>& args, const fs::path& dir)
      : out_(dir / "stdout.txt"), err_(dir / "stderr.txt") {
    std::vector<std::string> argv_strings = {OCTOVK_PATH(OCTOVK_CLI)};
    argv_strings.insert(argv_strings.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& a : argv_strings) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t files;
    posix_spawn_file_actions_init(&files);
    posix_spawn_file_actions_addopen(&files, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&files, STDOUT_FILENO, out_.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&files, STDERR_FILENO, err_.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawnattr_t attributes;
    posix_spawnattr_init(&attributes);
    sigset_t none, defaults;
    sigemptyset(&none);
    sigemptyset(&defaults);
    for (const int sig : {SIGHUP, SIGINT, SIGTERM, SIGQUIT}) sigaddset(&defaults, sig);
    posix_spawnattr_setsigmask(&attributes, &none);
    posix_spawnattr_setsigdefault(&attributes, &defaults);
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    const int failed =
        posix_spawn(&pid_, argv_strings[0].c_str(), &files, &attributes, argv.data(), environ);
    posix_spawn_file_actions_destroy(&files);
    posix_spawnattr_destroy(&attributes);
    if (failed != 0) pid_ = -1;
  }
  ~OctovkProcess() {
    if (pid_ > 0 && !waited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  OctovkProcess(const OctovkProcess&) = delete;
  OctovkProcess& operator=(const OctovkProcess&) = delete;

  bool started() const { return pid_ > 0; }
  void signal(int sig) const { ::kill(pid_, sig); }
  /// Waits for the end: the exit status as a shell reports it (128+N for death by signal N).
  RunResult wait() {
    int status = 0;
    while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    waited_ = true;
    RunResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    r.out = readFile(out_);
    r.err = readFile(err_);
    fs::remove(out_);
    fs::remove(err_);
    return r;
  }

 private:
  fs::path out_, err_;
  pid_t pid_ = -1;
  bool waited_ = false;
};

/// Polls until `ready()` or `timeout` has passed; the result of the last poll.
template <typename Ready>
bool pollUntil(Ready ready, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!ready()) {
    if (std::chrono::steady_clock::now() > end) return false;
    ::usleep(2000);
  }
  return true;
}

/// A fresh directory per test under OCTOVK_TEST_TMP, removed when the test passed.
class Scratch {
 public:
  explicit Scratch(const std::string& prefix = "cli") {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = prefix + "." + std::string(info->test_suite_name()) + "." + info->name() +
                       "." + std::to_string(::getpid());
    std::replace(name.begin(), name.end(), '/', '_');  // parameterized names hold slashes
    dir_ = fs::path(OCTOVK_PATH(OCTOVK_TEST_TMP)) / name;
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
