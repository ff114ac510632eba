#include "shared/drivers/serial/pty.h"

#include <fcntl.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstring>
#include <utility>

namespace idi::drivers {

Result<PtyPair> PtyPair::Open() {
  int master = -1, slave = -1;
  char name[PATH_MAX] = {};
  termios tio{};
  ::cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  if (::openpty(&master, &slave, name, &tio, nullptr) != 0) {
    const int err = errno;
    return IoError(std::string("openpty failed: ") + std::strerror(err));
  }
  ::fcntl(master, F_SETFD, FD_CLOEXEC);
  ::fcntl(slave, F_SETFD, FD_CLOEXEC);
  PtyPair pair;
  pair.master_fd_ = master;
  pair.slave_fd_ = slave;
  pair.slave_path_ = name;
  return pair;
}

PtyPair::PtyPair(PtyPair&& other) noexcept
    : master_fd_(std::exchange(other.master_fd_, -1)),
      slave_fd_(std::exchange(other.slave_fd_, -1)),
      slave_path_(std::move(other.slave_path_)) {}

PtyPair& PtyPair::operator=(PtyPair&& other) noexcept {
  if (this != &other) {
    if (master_fd_ >= 0) ::close(master_fd_);
    if (slave_fd_ >= 0) ::close(slave_fd_);
    master_fd_ = std::exchange(other.master_fd_, -1);
    slave_fd_ = std::exchange(other.slave_fd_, -1);
    slave_path_ = std::move(other.slave_path_);
  }
  return *this;
}

PtyPair::~PtyPair() {
  if (master_fd_ >= 0) ::close(master_fd_);
  if (slave_fd_ >= 0) ::close(slave_fd_);
}

int PtyPair::ReleaseMaster() { return std::exchange(master_fd_, -1); }

}  // namespace idi::drivers
