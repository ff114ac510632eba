// A pseudo-terminal pair for device emulators: the emulator speaks on the master, the driver opens
// the slave path like a real serial port (/dev/pts/N). The pair keeps a slave descriptor open so the
// master sees no hang-up between driver reconnects.
#pragma once

#include <string>

#include "shared/util/status.h"

namespace idi::drivers {

class PtyPair {
 public:
  // A new pair with the slave in raw mode. IoError when the system has no ptys left.
  static Result<PtyPair> Open();

  PtyPair(PtyPair&& other) noexcept;
  PtyPair& operator=(PtyPair&& other) noexcept;
  PtyPair(const PtyPair&) = delete;
  PtyPair& operator=(const PtyPair&) = delete;
  ~PtyPair();

  const std::string& slave_path() const { return slave_path_; }
  int master_fd() const { return master_fd_; }
  // Hands the master descriptor to the caller (e.g. SerialPort::FromFd); the pair no longer closes it.
  int ReleaseMaster();

 private:
  PtyPair() = default;
  int master_fd_ = -1;
  int slave_fd_ = -1;
  std::string slave_path_;
};

}  // namespace idi::drivers
