#include "shared/util/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <vector>

namespace idi {
namespace {

std::string ErrnoText() { return std::strerror(errno); }

// The process's umask, read without changing it (umask() would change it for every thread for a
// moment); 022 where /proc does not say.
mode_t CurrentUmask() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("Umask:", 0) == 0) return static_cast<mode_t>(std::stoul(line.substr(6), nullptr, 8) & 0777);
  }
  return 022;
}

// The mode the file gets: the target's own when it is replaced, otherwise what creating it would
// give (0666 less the umask: 0640 under the units' UMask=0027), not mkstemp's 0600.
mode_t ModeFor(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) return st.st_mode & 07777;
  return 0666 & ~CurrentUmask();
}

Status WriteAll(int fd, std::string_view contents, const std::string& path) {
  std::size_t done = 0;
  while (done < contents.size()) {
    const ssize_t n = ::write(fd, contents.data() + done, contents.size() - done);
    if (n < 0) {
      if (errno == EINTR) {
        continue;
      }
      return IoError(path + ": write failed: " + ErrnoText());
    }
    done += static_cast<std::size_t>(n);
  }
  return Status::Ok();
}

// A target that exists and is not a regular file (a character device, a FIFO): written in place.
Status WriteInPlace(const std::string& path, std::string_view contents) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) return IoError(path + ": cannot open for writing: " + ErrnoText());
  Status st = WriteAll(fd, contents, path);
  if (::close(fd) != 0 && st.ok()) st = IoError(path + ": close failed: " + ErrnoText());
  return st;
}

// The file a symbolic link at `path` ends at (links of links followed; a relative link is taken from
// the link's folder); `path` itself when it is not a link. ELOOP-like chains stop after 40 links.
std::string FollowLinks(const std::string& path) {
  namespace fs = std::filesystem;
  fs::path p(path);
  std::error_code ec;
  for (int i = 0; i < 40 && fs::is_symlink(p, ec); ++i) {
    const fs::path to = fs::read_symlink(p, ec);
    if (ec) break;
    p = to.is_absolute() ? to : p.parent_path() / to;
  }
  return p.string();
}

// The descriptor a name stands for (/dev/stdout, /dev/stderr, /dev/fd/N, /proc/self/fd/N), or -1.
// Reopening it by its /proc link would give a new file offset and drop O_APPEND, and its target may
// not be a name at all ("pipe:[1234]").
int DescriptorOf(const std::string& path) {
  if (path == "/dev/stdin") return 0;
  if (path == "/dev/stdout") return 1;
  if (path == "/dev/stderr") return 2;
  for (const std::string prefix : {"/dev/fd/", "/proc/self/fd/"}) {
    if (path.rfind(prefix, 0) != 0 || path.size() == prefix.size() || path.size() > prefix.size() + 9) continue;
    const std::string digits = path.substr(prefix.size());
    if (digits.find_first_not_of("0123456789") != std::string::npos) return -1;
    return std::stoi(digits);
  }
  return -1;
}

bool WritableDescriptor(int fd) {
  const int flags = ::fcntl(fd, F_GETFL);
  return flags >= 0 && (flags & O_ACCMODE) != O_RDONLY;
}

}  // namespace

std::string OutputTarget(const std::string& path) { return FollowLinks(path); }

std::vector<std::string> UniqueOutputNames(const std::vector<std::string>& paths, const std::string& suffix) {
  std::vector<std::string> names(paths.size()), stems(paths.size());
  std::set<std::string> taken;
  std::map<std::string, int> next;  // per stem, the next number to try
  for (std::size_t i = 0; i < paths.size(); ++i) {
    stems[i] = std::filesystem::path(paths[i]).stem().string();
    if (next.count(stems[i])) continue;
    next[stems[i]] = 2;
    names[i] = stems[i] + suffix;
    taken.insert(names[i]);
  }
  for (std::size_t i = 0; i < paths.size(); ++i) {
    if (!names[i].empty()) continue;
    int& n = next[stems[i]];
    do {
      names[i] = stems[i] + "_" + std::to_string(n++) + suffix;
    } while (!taken.insert(names[i]).second);
  }
  return names;
}

Status WriteFileAtomically(const std::string& requested, std::string_view contents) {
  namespace fs = std::filesystem;
  if (const int fd = DescriptorOf(requested); fd >= 0) {
    if (!WritableDescriptor(fd)) return IoError(requested + ": not open for writing");
    return WriteAll(fd, contents, requested);
  }
  const std::string path = FollowLinks(requested);
  struct stat existing {};
  // stat of the name asked for: the kernel follows every link, /proc's too.
  if (::stat(requested.c_str(), &existing) == 0 && !S_ISREG(existing.st_mode)) {
    if (S_ISDIR(existing.st_mode)) return InvalidArgument(requested + ": is a folder, expected a file name");
    return WriteInPlace(requested, contents);
  }
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    return NotFound(path + ": folder " + dir.string() + " does not exist");
  }
  std::string tmpl = (dir / ("." + target.filename().string() + ".tmpXXXXXX")).string();
  std::vector<char> name(tmpl.begin(), tmpl.end());
  name.push_back('\0');
  const int fd = ::mkostemp(name.data(), O_CLOEXEC);
  if (fd < 0) {
    return IoError(path + ": cannot create a temporary file: " + ErrnoText());
  }
  const std::string tmp_path(name.data());
  Status st = WriteAll(fd, contents, path);
  if (st.ok() && ::fchmod(fd, ModeFor(path)) != 0) {
    st = IoError(path + ": chmod failed: " + ErrnoText());
  }
  if (st.ok() && ::fsync(fd) != 0) {
    st = IoError(path + ": fsync failed: " + ErrnoText());
  }
  if (::close(fd) != 0 && st.ok()) {
    st = IoError(path + ": close failed: " + ErrnoText());
  }
  if (st.ok() && ::rename(tmp_path.c_str(), path.c_str()) != 0) {
    st = IoError(path + ": rename failed: " + ErrnoText());
  }
  if (!st.ok()) {
    ::unlink(tmp_path.c_str());
    return st;
  }
  const int dir_fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (dir_fd >= 0) {
    ::fsync(dir_fd);
    ::close(dir_fd);
  }
  return Status::Ok();
}

Status CheckOutputFile(const std::string& path, const std::string& what) {
  namespace fs = std::filesystem;
  if (path.empty()) return Status::Ok();
  // As WriteFileAtomically will: a descriptor, a device or FIFO in place, a link's file.
  if (const int fd = DescriptorOf(path); fd >= 0) {
    return WritableDescriptor(fd) ? Status::Ok() : IoError(what + " " + path + ": not open for writing");
  }
  const fs::path target(FollowLinks(path));
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (fs::is_directory(path, ec)) return InvalidArgument(what + " " + path + ": is a folder, expected a file name");
  struct stat existing {};
  if (::stat(path.c_str(), &existing) == 0 && !S_ISREG(existing.st_mode)) {
    if (::access(path.c_str(), W_OK) != 0) return IoError(what + " " + path + ": cannot write it: " + ErrnoText());
    return Status::Ok();
  }
  if (!fs::is_directory(dir, ec)) return NotFound(what + " " + path + ": folder " + dir.string() + " does not exist");
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    return IoError(what + " " + path + ": cannot write in " + dir.string() + ": " + ErrnoText());
  }
  return Status::Ok();
}

Status CheckOutputFolder(const std::string& path, const std::string& what) {
  namespace fs = std::filesystem;
  if (path.empty()) return Status::Ok();
  std::error_code ec;
  fs::path at = fs::absolute(fs::path(path), ec);
  if (ec) return IoError(what + " " + path + ": " + ec.message());
  while (!fs::exists(at, ec) && at.has_parent_path() && at.parent_path() != at) at = at.parent_path();
  if (!fs::is_directory(at, ec)) return InvalidArgument(what + " " + path + ": " + at.string() + " is not a folder");
  if (::access(at.c_str(), W_OK | X_OK) != 0) {
    return IoError(what + " " + path + ": cannot write in " + at.string() + ": " + ErrnoText());
  }
  return Status::Ok();
}

Status CheckNewOutputFolder(const std::string& path,
                            const std::string& what,
                            const std::vector<std::string>& may_hold) {
  namespace fs = std::filesystem;
  IDI_RETURN_IF_ERROR(CheckOutputFolder(path, what));
  std::error_code ec;
  if (!path.empty() && fs::is_symlink(path, ec) && !fs::exists(path, ec)) {
    return InvalidArgument(what + " " + path + ": it is a link to " + fs::read_symlink(path, ec).string() +
                           ", which does not exist");
  }
  if (path.empty() || !fs::is_directory(path, ec)) return Status::Ok();  // made by the run
  for (fs::directory_iterator it(path, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::error_code kind_ec;
    if (std::find(may_hold.begin(), may_hold.end(), name) != may_hold.end() && it->is_directory(kind_ec)) continue;
    return InvalidArgument(what + " " + path + ": the folder is not empty (it holds '" + name +
                           "'; give a new or empty folder, results of two runs would mix)");
  }
  // Nothing has run yet: the command line's folder is at fault (exit 2).
  if (ec) return InvalidArgument(what + " " + path + ": cannot list the folder: " + ec.message());
  return Status::Ok();
}

namespace {

// What identifies the file a path leads to: its absolute path once every link is resolved (a link to a
// file not made yet included: the write will follow it), and its device and inode when it exists. Two
// paths name one file when they share a key.
std::vector<std::string> FileKeys(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path absolute = fs::absolute(FollowLinks(path), ec);
  fs::path resolved = fs::weakly_canonical(absolute, ec);
  if (ec) resolved = absolute.lexically_normal();
  std::vector<std::string> keys = {"path " + resolved.string()};
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    keys.push_back("inode " + std::to_string(st.st_dev) + " " + std::to_string(st.st_ino));
  }
  return keys;
}

// Whether WriteFileAtomically writes `path` in place rather than replacing it: an open descriptor
// (/dev/stdout, /dev/fd/N), or a file that exists (after its links) and is neither a regular file nor a
// folder (a device, a FIFO).
bool IsWrittenInPlace(const std::string& path) {
  if (DescriptorOf(path) >= 0) return true;
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
}

}  // namespace

bool SameFile(const std::string& a, const std::string& b) {
  const std::vector<std::string> ka = FileKeys(a), kb = FileKeys(b);
  return std::any_of(
      ka.begin(), ka.end(), [&kb](const std::string& k) { return std::find(kb.begin(), kb.end(), k) != kb.end(); });
}

// Indexed by key rather than compared pair by pair: a command with thousands of images and as many
// overlays makes a few file-system calls per file, not per pair.
Status CheckDistinctFiles(const std::vector<NamedFile>& inputs,
                          const std::vector<NamedFile>& outputs,
                          const std::string& command) {
  std::map<std::string, const NamedFile*> input_of, output_of;
  for (const NamedFile& in : inputs) {
    if (in.path.empty()) continue;
    for (std::string& key : FileKeys(in.path)) input_of.emplace(std::move(key), &in);
  }
  for (const NamedFile& out : outputs) {
    if (out.path.empty()) continue;
    const std::vector<std::string> keys = FileKeys(out.path);
    for (const std::string& key : keys) {
      const auto it = input_of.find(key);
      if (it == input_of.end()) continue;
      const NamedFile& in = *it->second;
      return InvalidArgument(command + ": " + out.option + " " + out.path + " is the same file as the input " +
                             in.option + " " + in.path + ": writing it would destroy the input (name another file)");
    }
    // A descriptor (/dev/stdout), a device (/dev/null) or a pipe is written in place, not replaced: two
    // outputs sent there are both written (two discarded, or both on one stream).
    if (IsWrittenInPlace(out.path)) continue;
    for (const std::string& key : keys) {
      const auto it = output_of.find(key);
      if (it == output_of.end()) continue;
      const NamedFile& other = *it->second;
      return InvalidArgument(command + ": " + other.option + " " + other.path + " and " + out.option + " " + out.path +
                             " are the same file: one would replace the other (name two files)");
    }
    for (const std::string& key : keys) output_of.emplace(key, &out);
  }
  return Status::Ok();
}

Result<std::string> ReadFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    // exists() is false too when a folder on the way may not be searched: say so.
    if (ec == std::errc::permission_denied) return InvalidArgument(path + ": cannot open for reading: " + ec.message());
    return NotFound(path + ": no such file");
  }
  if (std::filesystem::is_directory(path, ec)) {
    return InvalidArgument(path + ": is a folder, expected a file");
  }
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int error = errno;
    const std::string why = error != 0 ? std::string(": ") + std::strerror(error) : std::string();
    // A file the user may not read is bad input, like a missing one; other failures (too many open
    // files) are the run's.
    if (error == EACCES || error == EPERM) return InvalidArgument(path + ": cannot open for reading" + why);
    return IoError(path + ": cannot open for reading" + why);
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) {
    return IoError(path + ": read failed");
  }
  return ss.str();
}

}  // namespace idi
