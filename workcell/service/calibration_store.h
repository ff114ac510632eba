// The calibration in use, versioned and replaced atomically in the service's state directory:
//
//   <state>/calibration/versions/0001/{robot1.yaml, robot2.yaml, rail.yaml, ptu-left.yaml, ..., meta.json}
//   <state>/calibration/current -> versions/0007      (a symlink, swapped with rename(2))
//
// A new version is written completely in a temporary folder, synced, renamed into versions/, and only
// then made current by renaming a fresh symlink over `current`. A process killed at any point leaves
// the previous calibration current and intact; an interrupted version is removed at the next start.
#pragma once

#include <chrono>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "shared/util/status.h"

namespace idi::workcell {

struct CalibrationVersion {
  int number = 0;
  std::string dir;                          // absolute folder of this version
  int64_t created_unix_s = 0;
  std::map<std::string, std::string> items;  // item name -> file name (e.g. "robot1" -> "robot1.yaml")
};

class CalibrationStore {
 public:
  explicit CalibrationStore(std::string state_dir);

  // Creates the folders and removes leftovers of interrupted commits.
  Status Open();
  // The current version, nullopt when there is none yet.
  Result<std::optional<CalibrationVersion>> Current() const;
  // Path of an item in the current version; NotFound when absent.
  Result<std::string> CurrentItemPath(const std::string& item) const;
  // Makes a new current version holding the current items plus `updates` (item -> file contents;
  // file name <item>.yaml), less the items in `drop` (ones the updates make stale). Returns the new
  // version.
  Result<CalibrationVersion> Commit(const std::map<std::string, std::string>& updates,
                                    int64_t now_unix_s,
                                    const std::vector<std::string>& drop = {});

  const std::string& root() const { return root_; }

 private:
  std::string root_;  // <state>/calibration
};

}  // namespace idi::workcell
