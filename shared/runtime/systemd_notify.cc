#include "shared/runtime/systemd_notify.h"

#ifdef IDI_HAVE_SYSTEMD
#include <systemd/sd-daemon.h>
#endif

namespace idi {
namespace {
void Notify([[maybe_unused]] const std::string& state) {
#ifdef IDI_HAVE_SYSTEMD
  sd_notify(0, state.c_str());
#endif
}
}  // namespace

void NotifyReady() { Notify("READY=1"); }
void NotifyStopping() { Notify("STOPPING=1"); }
void NotifyWatchdog() { Notify("WATCHDOG=1"); }
void NotifyStatus(const std::string& status) { Notify("STATUS=" + status); }

std::optional<std::chrono::microseconds> WatchdogPeriod() {
#ifdef IDI_HAVE_SYSTEMD
  uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
    return std::chrono::microseconds(usec);
  }
#endif
  return std::nullopt;
}

}  // namespace idi
