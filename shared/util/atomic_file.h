// Results and calibration files are written atomically: a temporary file in the same folder, fsync,
// rename over the target, fsync the folder. A reader sees the old file or the new one, never half.
#pragma once

#include <string>
#include <string_view>

#include "shared/util/status.h"

namespace idi {

Status WriteFileAtomically(const std::string& path, std::string_view contents);

// Whether WriteFileAtomically(path) can succeed, checked before a long run rather than after it: the
// folder exists and may be written, and `path` is not a folder. `what` (an option, e.g. "--out") starts
// the message. Empty paths (an output not asked for) are fine.
Status CheckOutputFile(const std::string& path, const std::string& what);
// The same for a folder of outputs, without making it: it is a writable folder, or the nearest of its
// parents that exists is one (so that it can be made).
Status CheckOutputFolder(const std::string& path, const std::string& what);

// Reads a whole file; NotFound if it does not exist, IoError if it cannot be read.
Result<std::string> ReadFile(const std::string& path);

}  // namespace idi
