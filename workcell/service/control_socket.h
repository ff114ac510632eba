// The operator control socket: a local Unix-domain stream socket owned by the service, mode 0660 and
// group-owned by the operators' group, so only members of that group (and root) can control the cell.
// No network listener. One request line per connection, one reply line (control_protocol.h). Up to
// kMaxControlClients connections are open at once; one that sends no complete line within the client
// timeout gets an error reply and is closed.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "workcell/service/control_protocol.h"

namespace idi::workcell {

inline constexpr std::size_t kMaxControlClients = 16;

struct ControlServerOptions {
  std::string path = "/run/idi-workcell/control.sock";
  std::string group;  // empty: keep the service's group
  std::chrono::milliseconds client_timeout{2000};
};

class ControlServer {
 public:
  using Handler = std::function<nlohmann::json(const ControlRequest&)>;

  // Binds and starts serving on a background thread; the path's folder is made (0755) when missing.
  // FailedPrecondition if another process is listening on the path; InvalidArgument for an unknown
  // group or a path too long for a socket; IoError naming the folder when it cannot be made.
  static Result<std::unique_ptr<ControlServer>> Start(const ControlServerOptions& options, Handler handler);
  ~ControlServer();
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  // Stops serving and removes the socket file.
  void Stop();
  uint64_t requests_served() const { return served_.load(); }
  uint64_t requests_rejected() const { return rejected_.load(); }

 private:
  ControlServer(ControlServerOptions options, Handler handler, int listen_fd, int wake_read, int wake_write);
  void Serve();

  ControlServerOptions options_;
  Handler handler_;
  int listen_fd_ = -1;
  int wake_read_ = -1, wake_write_ = -1;
  std::atomic<bool> stopping_{false};
  std::atomic<uint64_t> served_{0}, rejected_{0};
  std::thread thread_;
};

// Client: sends one request and returns the reply object. Unavailable-style errors (no service
// running, permission denied) come back as FailedPrecondition with the path named.
Result<nlohmann::json> SendControlRequest(const std::string& path,
                                          const ControlRequest& request,
                                          std::chrono::milliseconds timeout = std::chrono::milliseconds(5000));

}  // namespace idi::workcell
