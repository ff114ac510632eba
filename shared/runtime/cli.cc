#include "shared/runtime/cli.h"

#include <spdlog/spdlog.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <sstream>

#include "shared/runtime/logging.h"

#ifndef IDI_VERSION
#define IDI_VERSION "unknown"
#endif

namespace idi {

int ExitCodeFor(const Status& status) {
  if (status.ok()) {
    return kExitOk;
  }
  switch (status.code()) {
    case StatusCode::kInvalidArgument:
    case StatusCode::kNotFound:
    case StatusCode::kParseError:
    case StatusCode::kOutOfRange:
      return kExitBadInput;
    default:
      return kExitFailed;
  }
}

CliApp::CliApp(const std::string& description, const std::string& program) : app(description, program) {
  app.set_version_flag("--version", std::string(program) + " " + IDI_VERSION);
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "off"}));
  app.add_flag("-q,--quiet", quiet, "only warnings and errors on stderr");
  app.require_subcommand(1);
  app.fallthrough();
}

CLI::App* CliApp::AddCommand(CLI::App* parent,
                             const std::string& name,
                             const std::string& description,
                             std::function<Status()> run) {
  CLI::App* sub = parent->add_subcommand(name, description);
  sub->parse_complete_callback([this, run = std::move(run)] { selected = run; });
  return sub;
}

namespace {

int ParseAndRun(CliApp& cli, int argc, char** argv) {
  try {
    try {
      cli.app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
      return cli.app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
      return cli.app.exit(e);
    } catch (const CLI::CallForVersion& e) {
      return cli.app.exit(e);
    } catch (const CLI::ParseError& e) {
      cli.app.exit(e);
      return kExitBadInput;
    }
    LoggingOptions log;
    log.program = cli.app.get_name();
    ParseLogLevel(cli.log_level, &log.level);
    if (cli.quiet && log.level < spdlog::level::warn) {
      log.level = spdlog::level::warn;
    }
    InitLogging(log);
    if (!cli.selected) {
      std::fprintf(stderr, "%s", cli.app.help().c_str());
      return kExitBadInput;
    }
    const Status st = cli.selected();
    if (!st.ok()) {
      spdlog::error("{}", st.message());
      return ExitCodeFor(st);
    }
    return kExitOk;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: fatal: %s\n", cli.app.get_name().c_str(), e.what());
    return kExitFailed;
  }
}

// Whether everything written to stdout reached it: the results of a run whose stdout is a full disk or
// a closed descriptor are lost, and a script must not take exit 0 for them. A write that failed while
// the command ran leaves the stream's error flag set; its reason is known only when the final flush
// fails too (errno is long overwritten by then otherwise), and only then is it given.
int CheckStandardOutput(const std::string& program, int exit_code) {
  const bool failed_before = std::cout.fail() || std::ferror(stdout);
  errno = 0;
  std::cout.flush();  // synced with stdio: flushes stdout, and fails when that does
  int error = errno;
  const bool cout_flushed = !std::cout.fail();
  errno = 0;
  const bool flushed = std::fflush(stdout) == 0;
  if (!flushed) error = errno;
  if (flushed && cout_flushed && !std::ferror(stdout)) return exit_code;
  // A reason only for a write that failed here: one that failed while the command ran left none.
  const std::string why = !failed_before && error != 0 ? std::string(": ") + std::strerror(error) : std::string();
  std::fprintf(
      stderr, "%s: writing to standard output failed%s (the results are incomplete)\n", program.c_str(), why.c_str());
  return exit_code == kExitOk ? kExitFailed : exit_code;
}

}  // namespace

int RunCli(CliApp& cli, int argc, char** argv) {
  const int exit_code = ParseAndRun(cli, argc, argv);
  return CheckStandardOutput(cli.app.get_name(), exit_code);
}

Result<std::vector<double>> ParseNumberList(const std::string& text,
                                            std::size_t expected_count,
                                            const std::string& what) {
  std::vector<double> out;
  // getline yields no field after a final comma: "1,2," would read as two numbers.
  if (!text.empty() && text.back() == ',') {
    return InvalidArgument(what + ": a number is missing after the last comma in '" + text + "'");
  }
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    while (used < item.size() && std::isspace(static_cast<unsigned char>(item[used]))) {
      ++used;
    }
    if (item.empty() || used != item.size() || !std::isfinite(v)) {
      return InvalidArgument(what + ": '" + item + "' is not a finite number (in '" + text + "')");
    }
    out.push_back(v);
  }
  if (expected_count != 0 && out.size() != expected_count) {
    return InvalidArgument(what + ": expected " + std::to_string(expected_count) + " comma-separated numbers, got " +
                           std::to_string(out.size()) + " in '" + text + "'");
  }
  return out;
}

}  // namespace idi
