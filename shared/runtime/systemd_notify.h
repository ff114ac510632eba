// systemd service notifications (Type=notify): readiness, watchdog pings, status text, stopping.
// Outside systemd ($NOTIFY_SOCKET unset) every call is a cheap no-op.
#pragma once

#include <chrono>
#include <optional>
#include <string>

namespace idi {

void NotifyReady();
void NotifyStopping();
void NotifyWatchdog();
void NotifyStatus(const std::string& status);
// The watchdog period systemd expects pings within ($WATCHDOG_USEC), if enabled for this process.
std::optional<std::chrono::microseconds> WatchdogPeriod();

}  // namespace idi
