// The octovk commands' output files, all or nothing: every output is written to a temporary file
// beside it and synced, and only then are they renamed into place, each replaced file kept under a
// backup name until all renames are done so that a failure puts every one back. SIGHUP, SIGINT
// and SIGTERM remove the temporaries; those of a killed run are removed by the next run. Runs
// that commit into the same directories at once take turns (flock on the directories), so that
// a set of outputs is always one run's. An output that is a symlink is written at its target.
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "cli.hpp"

namespace octovk::cli {

namespace {

namespace fs = std::filesystem;

// Every temporary name holds this after the output's name: ".NAME.octovk.tmp-PID.EXT" for a
// new file, ".NAME.octovk.tmp-PID.old" for a replaced one kept until all renames are done.
constexpr const char* kTemporaryTag = ".octovk.tmp-";
constexpr const char* kBackupSuffix = ".old";

// The paths a signal must remove, and the lock that keeps the signal's cleanup out of a commit
// (a signal during the renames takes effect after them, so the outputs are never half replaced).
std::mutex& cleanupMutex() {
  static std::mutex mutex;
  return mutex;
}
std::set<std::string>& cleanupPaths() {
  static std::set<std::string> paths;
  return paths;
}

// Runs on its own thread: the signals are blocked everywhere else, so cleanup here needs no
// async-signal-safety and cannot interleave with a commit. Ends the process by the same signal.
void cleanUpOnSignal(sigset_t signals) {
  int sig = 0;
  while (::sigwait(&signals, &sig) != 0) {
  }
  cleanupMutex().lock();  // held until the end: no commit may start now
  for (const std::string& path : cleanupPaths()) ::unlink(path.c_str());
  ::signal(sig, SIG_DFL);
  sigset_t one;
  sigemptyset(&one);
  sigaddset(&one, sig);
  ::pthread_sigmask(SIG_UNBLOCK, &one, nullptr);
  ::raise(sig);  // the default action: the parent sees death by `sig` (a shell's 128+sig)
  std::_Exit(128 + sig);
}

// The most digits of a process id in a temporary name (pid_t is 32 bits).
constexpr std::size_t kPidDigits = 10;

// The directory `path` is in ("." for a bare name).
fs::path directoryOf(const std::string& path) {
  const fs::path target(path);
  return target.has_parent_path() ? target.parent_path() : fs::path(".");
}

// The longest file name the directory of `path` takes (NAME_MAX where it cannot say).
std::size_t nameMax(const std::string& path) {
  errno = 0;
  const long max = ::pathconf(directoryOf(path).c_str(), _PC_NAME_MAX);
  return max > 0 ? static_cast<std::size_t>(max) : std::size_t{NAME_MAX};
}

// ".NAME.octovk.tmp-" for the output `path` whose temporaries end in `ext` (or ".old"). A name
// too long for the directory with that around it is cut, and a hash of the whole name keeps
// outputs that share the cut part apart: the temporaries of any valid name fit.
std::string temporaryNamePrefix(const std::string& path, const std::string& ext) {
  const std::string name = fs::path(path).filename().string();
  const std::size_t max = nameMax(path);
  const std::size_t around = 1 + std::strlen(kTemporaryTag) + kPidDigits +
                             std::max(ext.size(), std::strlen(kBackupSuffix));
  std::string prefix = ".";  // appended, not "." + name: GCC 12's -Wrestrict misfires on that
  if (around + name.size() <= max) {
    prefix.append(name);
  } else {
    std::uint64_t hash = 14695981039346656037ull;  // FNV-1a: the same in every run
    for (const char c : name) hash = (hash ^ static_cast<unsigned char>(c)) * 1099511628211ull;
    char tail[20];
    std::snprintf(tail, sizeof(tail), "~%016llx", static_cast<unsigned long long>(hash));
    const std::size_t keep = max > around + 17 ? max - around - 17 : 0;
    prefix.append(name, 0, keep).append(tail);
  }
  return prefix.append(kTemporaryTag);
}

// "DIR/.NAME.octovk.tmp-" for the output `path`.
std::string temporaryPrefix(const std::string& path, const std::string& ext) {
  return (fs::path(path).parent_path() / temporaryNamePrefix(path, ext)).string();
}

// The file an output `path` names: `path`, or where its symlinks lead (a link is kept and its
// target written, as a shell's '>' does). A loop or an unreadable link is a UsageError.
std::string followLinks(const std::string& path) {
  fs::path at(path);
  for (int hops = 0; hops < 40; ++hops) {
    struct stat st;
    if (::lstat(at.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return at.string();
    std::error_code ec;
    const fs::path next = fs::read_symlink(at, ec);
    if (ec)
      throw UsageError("cannot write '" + path + "': " + ec.message() +
                       "; choose another output path (nothing was done)");
    at = next.is_absolute() ? next : at.parent_path() / next;
  }
  throw UsageError("cannot write '" + path + "': " + std::strerror(ELOOP) +
                   "; choose another output path (nothing was done)");
}

// Removes what killed runs (SIGKILL, a crash, a power cut) left for `path`: temporaries and
// backups whose process is gone. A backup whose output is missing is put back in its place.
void removeStaleTemporaries(const std::string& path, const std::string& ext) {
  const fs::path dir = directoryOf(path);
  const std::string prefix = temporaryNamePrefix(path, ext);
  std::error_code ec;
  std::vector<std::pair<fs::path, bool>> stale;  // path, is a backup
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    std::size_t digits = prefix.size();
    while (digits < name.size() && name[digits] >= '0' && name[digits] <= '9') ++digits;
    const std::string rest = name.substr(digits);
    if (digits == prefix.size() || digits - prefix.size() > 9 ||
        (rest != ext && rest != kBackupSuffix))
      continue;
    const auto pid =
        static_cast<pid_t>(std::stol(name.substr(prefix.size(), digits - prefix.size())));
    // Our own id: a run before ours that had it (the names are per output, and ours are not made).
    // Id 0 would ask about our process group: never a run's.
    if (pid <= 0 || (pid != ::getpid() && !(::kill(pid, 0) != 0 && errno == ESRCH))) continue;
    stale.emplace_back(it->path(), rest == kBackupSuffix);
  }
  for (const auto& [file, backup] : stale) {
    struct stat st;
    if (backup && ::lstat(path.c_str(), &st) != 0 && errno == ENOENT)
      ::rename(file.c_str(), path.c_str());
    else
      ::unlink(file.c_str());
  }
}

// `message` with every mention of `from` replaced by `to`.
std::string replaced(std::string message, const std::string& from, const std::string& to) {
  for (std::size_t at = message.find(from); at != std::string::npos;
       at = message.find(from, at + to.size()))
    message.replace(at, from.size(), to);
  return message;
}

// The file `path` names (through symlinks), if it exists.
bool fileId(const std::string& path, dev_t& dev, ino_t& ino) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) return false;
  dev = st.st_dev;
  ino = st.st_ino;
  return true;
}

// Syncs the directory of `path`, so that the renames in it survive a power cut. Best effort: the
// files are in place already, and some file systems cannot sync a directory.
void syncDirectoryOf(const std::string& path) {
  const int fd = ::open(directoryOf(path).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

// Exclusive flocks on the directories of `paths`, taken in the order of their device and inode
// numbers (so that two runs never wait on each other), held while alive: runs that commit into
// the same directories take turns, and a set of outputs is never half one run's, half another's.
// Best effort: a directory that cannot be opened or locked (some network file systems) is not.
class DirectoryLocks {
 public:
  explicit DirectoryLocks(const std::vector<std::string>& paths) {
    struct Dir {
      dev_t dev;
      ino_t ino;
      int fd;
    };
    std::vector<Dir> dirs;
    for (const std::string& path : paths) {
      const int fd = ::open(directoryOf(path).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
      struct stat st;
      if (fd < 0) continue;
      if (::fstat(fd, &st) != 0) {
        ::close(fd);
        continue;
      }
      dirs.push_back({st.st_dev, st.st_ino, fd});
    }
    std::sort(dirs.begin(), dirs.end(), [](const Dir& a, const Dir& b) {
      return a.dev != b.dev ? a.dev < b.dev : a.ino < b.ino;
    });
    for (std::size_t i = 0; i < dirs.size(); ++i) {
      if (i > 0 && dirs[i].dev == dirs[i - 1].dev && dirs[i].ino == dirs[i - 1].ino) {
        ::close(dirs[i].fd);  // the same directory: locked once
        continue;
      }
      while (::flock(dirs[i].fd, LOCK_EX) != 0 && errno == EINTR) {
      }
      fds_.push_back(dirs[i].fd);  // locked, or not lockable: closed with the rest
    }
  }
  ~DirectoryLocks() {
    for (const int fd : fds_) ::close(fd);  // closing the last descriptor drops its lock
  }
  DirectoryLocks(const DirectoryLocks&) = delete;
  DirectoryLocks& operator=(const DirectoryLocks&) = delete;

 private:
  std::vector<int> fds_;
};

// Gives the new file `temporary` the owner (where allowed) and permission bits of the file it
// replaces, `old`: a read-only output stays read-only. Best effort, as cp does for a non-root user;
// set-id bits are not carried over to new content.
void keepOwnerAndMode(const std::string& temporary, const struct stat& old) {
  struct stat now;
  if (::stat(temporary.c_str(), &now) != 0) return;
  if (now.st_uid != old.st_uid || now.st_gid != old.st_gid) {
    if (::chown(temporary.c_str(), old.st_uid, old.st_gid) != 0) {
      // Another user's file: the group alone may still be ours to give.
      if (::chown(temporary.c_str(), static_cast<uid_t>(-1), old.st_gid) != 0) {
      }
    }
  }
  ::chmod(temporary.c_str(), old.st_mode & 01777);
}

}  // namespace

void installSignalCleanup() {
  // A file past `ulimit -f` fails its write (EFBIG), which is reported and cleaned up like any
  // write error, instead of SIGXFSZ killing the run and leaving its temporaries behind.
  ::signal(SIGXFSZ, SIG_IGN);
  sigset_t signals;
  sigemptyset(&signals);
  for (const int sig : {SIGHUP, SIGINT, SIGTERM}) {
    // A signal ignored by whoever started us (nohup, a background job) stays ignored.
    struct sigaction current {};
    if (::sigaction(sig, nullptr, &current) == 0 && current.sa_handler == SIG_IGN) continue;
    sigaddset(&signals, sig);
  }
  // Blocked before any thread exists, so that every thread (the Vulkan driver's too) inherits it
  // and only the cleanup thread takes these signals.
  sigset_t previous;
  ::pthread_sigmask(SIG_BLOCK, &signals, &previous);
  try {
    std::thread(cleanUpOnSignal, signals).detach();
  } catch (const std::exception&) {
    ::pthread_sigmask(SIG_SETMASK, &previous, nullptr);  // no thread: the default actions
  }
}

void checkOutputsDistinct(const std::vector<std::string>& outputs,
                          const std::vector<std::string>& inputs) {
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    const std::string& output = outputs[i];
    dev_t dev = 0;
    ino_t ino = 0;
    const bool exists = fileId(output, dev, ino);
    for (const std::string& input : inputs) {
      dev_t input_dev = 0;
      ino_t input_ino = 0;
      if (exists && fileId(input, input_dev, input_ino) && dev == input_dev && ino == input_ino)
        throw UsageError("output '" + output + "' is the input '" + input +
                         "' (the same file); write the output to another path");
    }
    std::error_code ec;
    const fs::path canonical = fs::weakly_canonical(fs::absolute(output, ec), ec);
    for (std::size_t j = 0; j < i; ++j) {
      dev_t other_dev = 0;
      ino_t other_ino = 0;
      const bool same_file = exists && fileId(outputs[j], other_dev, other_ino) &&
                             dev == other_dev && ino == other_ino;
      std::error_code other_ec;
      const bool same_path =
          canonical == fs::weakly_canonical(fs::absolute(outputs[j], other_ec), other_ec);
      if (same_file || same_path)
        throw UsageError("output '" + output + "' is the same file as output '" + outputs[j] +
                         "'; give each -o file once");
    }
    struct stat st;
    if (exists && ::stat(output.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
      throw UsageError("output '" + output +
                       "' exists and is not a regular file (a pipe, device or socket); give a "
                       "file name");
  }
}

OutputFiles::OutputFiles(const std::vector<std::string>& paths,
                         const std::vector<std::string>& inputs) {
  checkOutputsDistinct(paths, inputs);
  try {
    claim(paths);
  } catch (...) {
    removeTemporaries();  // no destructor runs for a constructor that throws
    throw;
  }
}

void OutputFiles::claim(const std::vector<std::string>& paths) {
  for (const std::string& path : paths) {
    Entry entry;
    entry.path = path;
    entry.target = followLinks(path);
    // The temporary keeps the name's extension (the writers choose the format by it); the
    // target's may differ.
    entry.ext = fs::path(path).extension().string();
    if (fs::path(entry.target).filename().string().size() > nameMax(entry.target))
      throw UsageError("cannot write '" + path + "': " + std::strerror(ENAMETOOLONG) +
                       "; choose another output path (nothing was done)");
    removeStaleTemporaries(entry.target, entry.ext);
    entry.temporary =
        temporaryPrefix(entry.target, entry.ext) + std::to_string(::getpid()) + entry.ext;
    // Created and listed under the lock: a signal between the two would leave it behind.
    const std::lock_guard<std::mutex> lock(cleanupMutex());
    const int fd = ::open(entry.temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0)
      throw UsageError("cannot write '" + path + "': " + std::strerror(errno) +
                       "; choose another output path (nothing was done)");
    ::close(fd);
    cleanupPaths().insert(entry.temporary);
    entries_.push_back(std::move(entry));
  }
}

OutputFiles::~OutputFiles() { removeTemporaries(); }

void OutputFiles::removeTemporaries() {
  const std::lock_guard<std::mutex> lock(cleanupMutex());
  for (const Entry& entry : entries_) {
    if (!committed_) ::unlink(entry.temporary.c_str());
    cleanupPaths().erase(entry.temporary);
  }
}

void OutputFiles::write(std::size_t index, const std::function<void(const std::string&)>& write) {
  Entry& entry = entries_.at(index);
  try {
    write(entry.temporary);
  } catch (const Error& e) {
    throw Error(e.code(), replaced(e.what(), entry.temporary, entry.path));
  }
  // On disk before any rename: a crash after the renames must not leave empty files in place.
  const int fd = ::open(entry.temporary.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0 || ::fsync(fd) != 0) {
    const std::string why = std::strerror(errno);
    if (fd >= 0) ::close(fd);
    throw Error(ErrorCode::kIo, "cannot write '" + entry.path + "': " + why);
  }
  ::close(fd);
  entry.written = true;
}

void OutputFiles::commit() {
  for (const Entry& entry : entries_)
    if (!entry.written)
      throw std::logic_error("output '" + entry.path + "' committed before it was written");
  // Taken before the signal lock: a run waiting for another's commit can still be interrupted.
  std::vector<std::string> targets;
  for (const Entry& entry : entries_) targets.push_back(entry.target);
  const DirectoryLocks turn(targets);
  // Held throughout: a signal now is acted on after the renames (or the rollback).
  const std::lock_guard<std::mutex> lock(cleanupMutex());
  struct Replaced {
    const Entry* entry;
    std::string backup;  // empty: there was no file at entry->path
  };
  std::vector<Replaced> done;
  std::string failure;
  for (const Entry& entry : entries_) {
    Replaced step{&entry, {}};
    struct stat st;
    if (::lstat(entry.target.c_str(), &st) == 0) {
      keepOwnerAndMode(entry.temporary, st);
      step.backup =
          temporaryPrefix(entry.target, entry.ext) + std::to_string(::getpid()) + kBackupSuffix;
      ::unlink(step.backup.c_str());
      // A second name for the old file (the path keeps it until the rename replaces it); where
      // hard links are not supported the old file moves aside instead.
      if (::linkat(AT_FDCWD, entry.target.c_str(), AT_FDCWD, step.backup.c_str(), 0) != 0 &&
          ::rename(entry.target.c_str(), step.backup.c_str()) != 0) {
        failure = "cannot replace '" + entry.path + "': " + std::strerror(errno);
        break;
      }
    }
    if (::rename(entry.temporary.c_str(), entry.target.c_str()) != 0) {
      failure = "cannot write '" + entry.path + "': " + std::strerror(errno);
      if (!step.backup.empty()) {
        struct stat now;
        if (::lstat(entry.target.c_str(), &now) != 0)
          ::rename(step.backup.c_str(), entry.target.c_str());
        else
          ::unlink(step.backup.c_str());
      }
      break;
    }
    done.push_back(std::move(step));
  }
  if (!failure.empty()) {
    // Every output already replaced gets its old file back (or none, as before the run).
    bool restored = true;
    for (auto it = done.rbegin(); it != done.rend(); ++it) {
      const std::string& path = it->entry->path;
      const std::string& target = it->entry->target;
      if (it->backup.empty()) {
        ::unlink(target.c_str());
      } else if (::rename(it->backup.c_str(), target.c_str()) != 0) {
        failure += "; the previous '" + path + "' could not be put back and is kept as '" +
                   it->backup + "'";
        restored = false;
      }
    }
    throw Error(ErrorCode::kIo, failure + (restored ? " (no output was changed)" : ""));
  }
  for (const Replaced& step : done)
    if (!step.backup.empty()) ::unlink(step.backup.c_str());
  committed_ = true;
  for (const Entry& entry : entries_) {
    cleanupPaths().erase(entry.temporary);
    syncDirectoryOf(entry.target);
  }
}

}  // namespace octovk::cli
