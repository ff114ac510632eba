#include "workcell/service/control_socket.h"

#include <fcntl.h>
#include <grp.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

namespace idi::workcell {
namespace {

std::string Errno() { return std::strerror(errno); }

Result<sockaddr_un> SocketAddress(const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof(addr.sun_path)) {
    return InvalidArgument("control socket path '" + path + "' is empty or longer than " +
                           std::to_string(sizeof(addr.sun_path) - 1) + " bytes");
  }
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  return addr;
}

// Reads one line (without the newline) within `timeout`; fails on timeout, EOF before a newline, or
// more than kMaxRequestBytes.
Result<std::string> ReadLine(int fd, std::chrono::milliseconds timeout) {
  std::string line;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  char buf[4096];
  while (true) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return Timeout("no complete line within " + std::to_string(timeout.count()) + " ms");
    pollfd p{fd, POLLIN, 0};
    const int r = ::poll(&p, 1, static_cast<int>(left.count()));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) return IoError("poll: " + Errno());
    if (r == 0) continue;
    const ssize_t n = ::read(fd, buf, sizeof(buf));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return IoError("read: " + Errno());
    if (n == 0) return IoError("connection closed before a complete line");
    line.append(buf, static_cast<std::size_t>(n));
    const auto nl = line.find('\n');
    if (nl != std::string::npos) {
      line.resize(nl);
      return line;
    }
    if (line.size() > kMaxRequestBytes)
      return InvalidArgument("line longer than " + std::to_string(kMaxRequestBytes) + " bytes");
  }
}

Status WriteAll(int fd, const std::string& data) {
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::send(fd, data.data() + done, data.size() - done, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return IoError("write: " + Errno());
    done += static_cast<std::size_t>(n);
  }
  return Status::Ok();
}

// Makes the socket's folder and its missing parents (0755: operators of the socket's group must reach
// it whatever the service's umask); bind() does not make it. A folder that exists is left as it is.
Status MakeSocketFolder(const std::string& socket_path) {
  namespace fs = std::filesystem;
  const fs::path folder = fs::path(socket_path).parent_path();
  if (folder.empty()) return Status::Ok();  // "control.sock": the working folder
  std::vector<fs::path> missing;
  std::error_code ec;
  for (fs::path p = folder; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (::mkdir(it->c_str(), 0755) == 0) {
      ::chmod(it->c_str(), 0755);  // not through the umask (see the socket's mode below)
    } else if (errno != EEXIST) {
      return IoError(socket_path + ": cannot make the control socket's folder " + it->string() + ": " + Errno());
    }
  }
  if (!fs::is_directory(folder, ec)) {
    return IoError(socket_path + ": the control socket's folder " + folder.string() + " is not a folder");
  }
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<ControlServer>> ControlServer::Start(const ControlServerOptions& options, Handler handler) {
  IDI_ASSIGN_OR_RETURN(const sockaddr_un addr, SocketAddress(options.path));
  gid_t gid = static_cast<gid_t>(-1);
  if (!options.group.empty()) {
    const group* g = ::getgrnam(options.group.c_str());
    if (g == nullptr) return InvalidArgument("control socket group '" + options.group + "' does not exist");
    gid = g->gr_gid;
  }
  IDI_RETURN_IF_ERROR(MakeSocketFolder(options.path));
  // A socket file left by a crashed service is removed; one with a live listener is not.
  if (::access(options.path.c_str(), F_OK) == 0) {
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool live = probe >= 0 && ::connect(probe, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0;
    if (probe >= 0) ::close(probe);
    if (live) return FailedPrecondition(options.path + ": another idi-workcell service is already listening");
    ::unlink(options.path.c_str());
  }
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return IoError("control socket: " + Errno());
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    const std::string err = Errno();
    ::close(fd);
    return IoError(options.path + ": bind failed: " + err);
  }
  // 0660, set on the file rather than through the umask (which is the whole process's: a file another
  // thread wrote meanwhile would have been made with it). Nobody can connect before listen() anyway.
  if (::chmod(options.path.c_str(), 0660) != 0) {
    const std::string err = Errno();
    ::close(fd);
    ::unlink(options.path.c_str());
    return IoError(options.path + ": cannot make the socket 0660: " + err);
  }
  if (gid != static_cast<gid_t>(-1) && ::chown(options.path.c_str(), static_cast<uid_t>(-1), gid) != 0) {
    const std::string err = Errno();
    ::close(fd);
    ::unlink(options.path.c_str());
    return IoError(options.path + ": cannot give the socket to group '" + options.group + "': " + err);
  }
  if (::listen(fd, 8) != 0) {
    const std::string err = Errno();
    ::close(fd);
    ::unlink(options.path.c_str());
    return IoError(options.path + ": listen failed: " + err);
  }
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC | O_NONBLOCK) != 0) {
    ::close(fd);
    ::unlink(options.path.c_str());
    return IoError("control socket: pipe: " + Errno());
  }
  return std::unique_ptr<ControlServer>(new ControlServer(options, std::move(handler), fd, pipe_fds[0], pipe_fds[1]));
}

ControlServer::ControlServer(
    ControlServerOptions options, Handler handler, int listen_fd, int wake_read, int wake_write)
    : options_(std::move(options)),
      handler_(std::move(handler)),
      listen_fd_(listen_fd),
      wake_read_(wake_read),
      wake_write_(wake_write) {
  thread_ = std::thread([this] { Serve(); });
}

ControlServer::~ControlServer() { Stop(); }

void ControlServer::Stop() {
  if (stopping_.exchange(true)) return;
  const char c = 'x';
  [[maybe_unused]] const ssize_t n = ::write(wake_write_, &c, 1);
  if (thread_.joinable()) thread_.join();
  ::close(listen_fd_);
  ::close(wake_read_);
  ::close(wake_write_);
  ::unlink(options_.path.c_str());
}

// One thread, many clients: a client is read only when poll says it has bytes, so a silent one costs
// nothing until its deadline, and a stop from a second client is served meanwhile. Requests are
// handled one at a time, in the order their lines complete.
void ControlServer::Serve() {
  using Clock = std::chrono::steady_clock;
  struct Client {
    int fd;
    std::string line;
    Clock::time_point deadline;
  };
  std::vector<Client> clients;
  const auto send_us = std::chrono::duration_cast<std::chrono::microseconds>(options_.client_timeout).count();
  const timeval send_timeout{static_cast<time_t>(send_us / 1000000), static_cast<suseconds_t>(send_us % 1000000)};
  // Replies and closes; an empty reply closes without one.
  auto finish = [&](std::size_t k, const nlohmann::json& reply) {
    if (!reply.is_null()) (void)WriteAll(clients[k].fd, reply.dump() + "\n");
    ::close(clients[k].fd);
    clients.erase(clients.begin() + static_cast<std::ptrdiff_t>(k));
  };
  auto reject = [&](std::size_t k, const std::string& why) {
    ++rejected_;
    finish(k, ErrorReply("bad request: " + why));
  };
  while (!stopping_.load()) {
    std::vector<pollfd> p;
    p.push_back({wake_read_, POLLIN, 0});
    // At kMaxControlClients the listener waits (the kernel's backlog holds new ones) until one ends.
    const bool accepting = clients.size() < kMaxControlClients;
    p.push_back({accepting ? listen_fd_ : -1, POLLIN, 0});
    for (const Client& c : clients) p.push_back({c.fd, POLLIN, 0});
    int wait_ms = -1;
    const Clock::time_point now = Clock::now();
    for (const Client& c : clients) {
      const auto left = std::chrono::ceil<std::chrono::milliseconds>(c.deadline - now).count();
      wait_ms = wait_ms < 0 ? static_cast<int>(std::max<int64_t>(left, 0))
                            : std::min(wait_ms, static_cast<int>(std::max<int64_t>(left, 0)));
    }
    const int r = ::poll(p.data(), static_cast<nfds_t>(p.size()), wait_ms);
    if (r < 0) {
      if (errno == EINTR) continue;
      spdlog::error("control socket: poll failed: {}", Errno());
      break;
    }
    if (p[0].revents != 0) break;
    // Clients first (from the back, as finishing one removes it), then the listener: the indices of
    // p[2 + k] stay those of clients[k].
    for (std::size_t k = clients.size(); k-- > 0;) {
      const short ev = p[2 + k].revents;
      if (ev == 0) {
        if (Clock::now() >= clients[k].deadline) {
          reject(k, "no complete line within " + std::to_string(options_.client_timeout.count()) + " ms");
        }
        continue;
      }
      char buf[4096];
      const ssize_t n = ::read(clients[k].fd, buf, sizeof(buf));
      if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
      if (n < 0) {
        ++rejected_;
        finish(k, nlohmann::json());  // the connection is broken: nobody to answer
        continue;
      }
      if (n == 0) {
        reject(k, "connection closed before a complete line");
        continue;
      }
      std::string& line = clients[k].line;
      line.append(buf, static_cast<std::size_t>(n));
      const auto nl = line.find('\n');
      if (nl == std::string::npos) {
        if (line.size() > kMaxRequestBytes)
          reject(k, "line longer than " + std::to_string(kMaxRequestBytes) + " bytes");
        continue;
      }
      line.resize(nl);
      const Result<ControlRequest> request = ParseControlRequest(line);
      if (!request.ok()) {
        spdlog::warn("control socket: rejected a request: {}", request.status().message());
        reject(k, request.status().message());
        continue;
      }
      ++served_;
      finish(k, handler_(*request));
    }
    if ((p[1].revents & POLLIN) != 0) {
      const int client = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (client >= 0) {
        // A client that does not read its reply must not hold the socket: the reply's write gives up
        // after the client timeout too.
        ::setsockopt(client, SOL_SOCKET, SO_SNDTIMEO, &send_timeout, sizeof(send_timeout));
        clients.push_back({client, std::string(), Clock::now() + options_.client_timeout});
      }
    }
  }
  for (const Client& c : clients) ::close(c.fd);
}

Result<nlohmann::json> SendControlRequest(const std::string& path,
                                          const ControlRequest& request,
                                          std::chrono::milliseconds timeout) {
  IDI_ASSIGN_OR_RETURN(const sockaddr_un addr, SocketAddress(path));
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return IoError("control socket: " + Errno());
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    const int err = errno;
    ::close(fd);
    if (err == EACCES) {
      return FailedPrecondition(path + ": permission denied (is your user in the service's control group?)");
    }
    return FailedPrecondition(path + ": no idi-workcell service is listening (" + std::strerror(err) + ")");
  }
  Status st = WriteAll(fd, SerializeControlRequest(request) + "\n");
  if (!st.ok()) {
    ::close(fd);
    return st.WithContext(path);
  }
  const Result<std::string> line = ReadLine(fd, timeout);
  ::close(fd);
  if (!line.ok()) return line.status().WithContext(path + ": no reply");
  nlohmann::json reply = nlohmann::json::parse(*line, nullptr, false);
  if (reply.is_discarded() || !reply.is_object()) return DeviceError(path + ": the service sent a malformed reply");
  return reply;
}

}  // namespace idi::workcell
