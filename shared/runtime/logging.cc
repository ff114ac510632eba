#include "shared/runtime/logging.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <spdlog/sinks/stdout_color_sinks.h>
#ifdef IDI_HAVE_SYSTEMD
#include <spdlog/sinks/systemd_sink.h>
#endif

namespace idi {

bool StderrIsJournal() {
  const char* env = std::getenv("JOURNAL_STREAM");
  if (env == nullptr) {
    return false;
  }
  unsigned long long dev = 0, ino = 0;
  if (std::sscanf(env, "%llu:%llu", &dev, &ino) != 2) {
    return false;
  }
  struct stat st {};
  if (::fstat(STDERR_FILENO, &st) != 0) {
    return false;
  }
  return static_cast<unsigned long long>(st.st_dev) == dev && static_cast<unsigned long long>(st.st_ino) == ino;
}

void InitLogging(const LoggingOptions& options) {
  std::shared_ptr<spdlog::logger> logger;
  const bool journal = !options.force_stderr && (options.force_journal || StderrIsJournal());
#ifdef IDI_HAVE_SYSTEMD
  if (journal) {
    auto sink = std::make_shared<spdlog::sinks::systemd_sink_mt>(options.program);
    logger = std::make_shared<spdlog::logger>(options.program, sink);
    logger->set_pattern("%v");  // the journal stamps time, unit and priority itself
  }
#else
  (void)journal;
#endif
  if (!logger) {
    auto sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
    logger = std::make_shared<spdlog::logger>(options.program, sink);
    logger->set_pattern("%H:%M:%S.%e %^%L%$ %v");
  }
  logger->set_level(options.level);
  logger->flush_on(spdlog::level::warn);
  spdlog::set_default_logger(logger);
}

bool ParseLogLevel(const std::string& text, spdlog::level::level_enum* level) {
  static const std::pair<const char*, spdlog::level::level_enum> kLevels[] = {
      {"trace", spdlog::level::trace}, {"debug", spdlog::level::debug}, {"info", spdlog::level::info},
      {"warn", spdlog::level::warn},   {"error", spdlog::level::err},   {"off", spdlog::level::off}};
  for (const auto& [name, value] : kLevels) {
    if (text == name) {
      *level = value;
      return true;
    }
  }
  return false;
}

}  // namespace idi
