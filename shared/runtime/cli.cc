#include "shared/runtime/cli.h"

#include <spdlog/spdlog.h>

#include <cctype>
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

// "inf", "-Infinity", "nan": not a notation question; each option's own check says whether it takes them.
bool IsInfOrNan(std::string value) {
  if (!value.empty() && (value[0] == '+' || value[0] == '-')) value.erase(0, 1);
  for (char& c : value) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return value == "inf" || value == "infinity" || value == "nan";
}

// CLI11 reads numbers as strtod and strtoll with base 0 do: "0x10" is 16, and an integer's "010" is 8.
// Numbers on the command line are decimal: every numeric option of `app` and its subcommands refuses
// another form, and an integer's leading zeros are dropped before CLI11 reads it ("010" is 10).
void RequireDecimalNumbers(CLI::App* app) {
  for (CLI::Option* opt : app->get_options()) {
    if (opt->get_type_size_max() == 0) continue;  // a flag
    const std::string type = opt->get_type_name();
    const bool integer = type.rfind("INT", 0) == 0 || type.rfind("UINT", 0) == 0;
    if (!integer && type.rfind("FLOAT", 0) != 0) continue;
    // A transform runs before the option's other validators (CLI::Range would read "0x10" as 16).
    opt->transform(CLI::Validator(
        [integer](std::string& value) -> std::string {
          if (!integer && IsInfOrNan(value)) return std::string();
          if (!IsDecimalNumber(value)) return "'" + value + "' is not a decimal number";
          if (integer) {
            const std::size_t sign = value[0] == '-' || value[0] == '+' ? 1 : 0;
            std::size_t zeros = sign;
            while (zeros + 1 < value.size() && value[zeros] == '0' &&
                   std::isdigit(static_cast<unsigned char>(value[zeros + 1]))) {
              ++zeros;
            }
            value.erase(sign, zeros - sign);
          }
          return std::string();
        },
        ""));
  }
  for (CLI::App* sub : app->get_subcommands([](CLI::App*) { return true; })) RequireDecimalNumbers(sub);
}

int ParseAndRun(CliApp& cli, int argc, char** argv) {
  try {
    try {
      RequireDecimalNumbers(&cli.app);
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

bool IsDecimalNumber(std::string_view text) {
  const auto digits = [&text](std::size_t* i) {
    const std::size_t start = *i;
    while (*i < text.size() && std::isdigit(static_cast<unsigned char>(text[*i]))) ++*i;
    return *i - start;
  };
  std::size_t i = 0;
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) ++i;
  std::size_t mantissa = digits(&i);
  if (i < text.size() && text[i] == '.') {
    ++i;
    mantissa += digits(&i);
  }
  if (mantissa == 0) return false;
  if (i < text.size() && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    if (i < text.size() && (text[i] == '+' || text[i] == '-')) ++i;
    if (digits(&i) == 0) return false;
  }
  return i == text.size();
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
    // Spaces around a number are fine ("1, 2, 3"); the number itself is decimal (stod reads "0x10" as 16).
    std::size_t begin = 0, end = item.size();
    while (begin < end && std::isspace(static_cast<unsigned char>(item[begin]))) ++begin;
    while (end > begin && std::isspace(static_cast<unsigned char>(item[end - 1]))) --end;
    const std::string number = item.substr(begin, end - begin);
    double v = 0;
    bool read = IsDecimalNumber(number);
    if (read) {
      try {
        v = std::stod(number);
      } catch (const std::exception&) {
        read = false;  // out of range: beyond a double
      }
    }
    if (!read || !std::isfinite(v)) {
      return InvalidArgument(what + ": '" + item + "' is not a finite decimal number (in '" + text + "')");
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
