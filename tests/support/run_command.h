// Runs a command line through /bin/sh for integration tests: captures stdout, stderr and exit code.
#pragma once

#include <string>

namespace idi::test {

struct CommandResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

CommandResult RunCommand(const std::string& command_line);

// Folder for a test's files, removed by the caller (unique per process and name).
std::string MakeTempDir(const std::string& name);

}  // namespace idi::test
