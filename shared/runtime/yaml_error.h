// yaml-cpp's exceptions as this project's errors: "FILE:LINE: malformed YAML: what" (the line when yaml-cpp knows
// it). The configuration readers catch every YAML::Exception at their entry, so a value of the wrong
// type (a list where a name is expected, a map walked as a list) names the file and is bad input (exit
// 2), never an uncaught exception.
#pragma once

#include <yaml-cpp/exceptions.h>

#include <string>

#include "shared/util/status.h"

namespace idi {

inline Status YamlError(const std::string& source, const YAML::Exception& e) {
  const std::string where = e.mark.is_null() ? source : source + ":" + std::to_string(e.mark.line + 1);
  return ParseError(where + ": malformed YAML: " + e.msg);
}

}  // namespace idi
