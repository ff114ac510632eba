// Logging: spdlog to stderr for people, to the systemd journal (with priorities) when the process
// runs under systemd with its stderr connected to the journal.
#pragma once

#include <spdlog/spdlog.h>

#include <string>

namespace idi {

struct LoggingOptions {
  std::string program = "idi";
  spdlog::level::level_enum level = spdlog::level::info;
  // Journal: auto-detected from $JOURNAL_STREAM; force on or off with these.
  bool force_journal = false;
  bool force_stderr = false;
};

void InitLogging(const LoggingOptions& options);

// True when stderr is the journal stream systemd set up for this service ($JOURNAL_STREAM names
// the device and inode of the stream, and they match stderr's).
bool StderrIsJournal();

// Parses "trace|debug|info|warn|error|off"; false on anything else.
bool ParseLogLevel(const std::string& text, spdlog::level::level_enum* level);

}  // namespace idi
