// Results and calibration files are written atomically: a temporary file in the same folder, fsync,
// rename over the target, fsync the folder. A reader sees the old file or the new one, never half.
// A symbolic link is followed (the file it names is replaced, the link stays), and a target that is
// not a regular file (/dev/null, a FIFO, a terminal) is written in place: renaming over it would
// replace the device node or FIFO with a regular file. /dev/stdout, /dev/stderr, /dev/fd/N and
// /proc/self/fd/N are written to that descriptor (whatever it is: a pipe, a terminal, a file opened
// for appending), never renamed over.
#pragma once

#include <string>
#include <string_view>
#include <vector>

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
// CheckOutputFolder, and the folder is new or empty, so that a run's results are not mixed with an earlier
// run's: one holding anything but the entries named in `may_hold` (e.g. a folder the command itself keeps
// there between runs, if they are folders) is refused (InvalidArgument naming the folder and an entry it
// holds), as are a folder that cannot be listed and a link to nothing.
Status CheckNewOutputFolder(const std::string& path,
                            const std::string& what,
                            const std::vector<std::string>& may_hold = {});

// A file a command reads or writes, with the option that names it (for messages).
struct NamedFile {
  std::string option;  // e.g. "--out"
  std::string path;    // empty: not given
};

// The file WriteFileAtomically(path) replaces: the end of path's symbolic links (path itself when it is
// not one). For writers that rename a file of their own over an output.
std::string OutputTarget(const std::string& path);

// One output name per input path: <stem><suffix> for the first path of each stem, and
// <stem>_<n><suffix> (n = 2, 3, ...) for the others (a/cam.png, b/cam.png), skipping names that are
// taken, so that an input whose stem is unique always gets <stem><suffix>.
std::vector<std::string> UniqueOutputNames(const std::vector<std::string>& paths, const std::string& suffix);

// Whether two paths name one file: the same inode when both exist, else the same absolute path once
// the symbolic links of its existing part are resolved.
bool SameFile(const std::string& a, const std::string& b);

// Refuses (InvalidArgument, `command` starting the message) an output that is the same file as an
// input (writing it would destroy the input before or while it is read) or as another output (one
// would replace the other; not for a device, pipe or descriptor such as /dev/null or /dev/stdout,
// which is written in place). Empty paths are skipped. Checked before any work, like CheckOutputFile.
Status CheckDistinctFiles(const std::vector<NamedFile>& inputs,
                          const std::vector<NamedFile>& outputs,
                          const std::string& command);

// Reads a whole file; NotFound if it does not exist, InvalidArgument if it is a folder or may not be
// read (permission denied), IoError if reading it fails otherwise. Messages name the file and the reason.
Result<std::string> ReadFile(const std::string& path);

}  // namespace idi
