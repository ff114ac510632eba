// Shared scaffolding for the binaries' main(): CLI11 app with --version and logging flags, the
// project's exit codes (0 ok, 1 failed run, 2 bad usage or input), one top-level catch.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <string_view>

#include "shared/util/status.h"

namespace idi {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailed = 1;
inline constexpr int kExitBadInput = 2;

// Exit code for a status: 2 for bad input/usage/configuration, 1 for everything else.
int ExitCodeFor(const Status& status);

struct CliApp {
  CLI::App app;
  std::string log_level = "info";
  bool quiet = false;
  // Set by the chosen subcommand's parse callback; RunCli runs it after logging is set up.
  std::function<Status()> selected;

  CliApp(const std::string& description, const std::string& program);

  // Adds a subcommand whose run function is `run` (called with logging set up).
  CLI::App* AddCommand(CLI::App* parent,
                       const std::string& name,
                       const std::string& description,
                       std::function<Status()> run);
};

// Parses the command line, sets up logging, then runs the selected subcommand. Errors are logged to
// stderr with what and where; returns the process exit code. A run whose output could not all be
// written to stdout (a full disk, a closed descriptor) fails (exit 1) with the reason on stderr.
int RunCli(CliApp& cli, int argc, char** argv);

// Whether `text` is a number written in decimal: an optional sign, digits with an optional decimal
// point ("1", "-1.5", ".5", "5."), an optional exponent ("1e-3"). Not hexadecimal ("0x10"), "inf" or
// "nan", which strtod (and CLI11, through it) also read.
bool IsDecimalNumber(std::string_view text);

// Parses "x,y,z"-style lists of decimal numbers; InvalidArgument naming `what` on malformed input.
Result<std::vector<double>> ParseNumberList(const std::string& text,
                                            std::size_t expected_count,
                                            const std::string& what);

}  // namespace idi
