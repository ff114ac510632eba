#include "workcell/service/calibration_store.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "shared/util/atomic_file.h"

namespace idi::workcell {
namespace fs = std::filesystem;

namespace {

std::string VersionName(int n) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%04d", n);
  return buf;
}

void SyncDir(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

CalibrationStore::CalibrationStore(std::string state_dir) : root_((fs::path(state_dir) / "calibration").string()) {}

Status CalibrationStore::Open() {
  std::error_code ec;
  fs::create_directories(fs::path(root_) / "versions", ec);
  if (ec) return IoError(root_ + ": cannot create: " + ec.message());
  for (const auto& e : fs::directory_iterator(fs::path(root_) / "versions", ec)) {
    if (e.path().filename().string().rfind(".tmp-", 0) == 0) fs::remove_all(e.path(), ec);
  }
  fs::remove(fs::path(root_) / "current.tmp", ec);
  return Status::Ok();
}

Result<std::optional<CalibrationVersion>> CalibrationStore::Current() const {
  const fs::path link = fs::path(root_) / "current";
  std::error_code ec;
  if (!fs::is_symlink(link, ec)) return std::optional<CalibrationVersion>();
  const fs::path target = fs::read_symlink(link, ec);
  if (ec) return IoError(link.string() + ": " + ec.message());
  const fs::path dir = fs::path(root_) / target;
  IDI_ASSIGN_OR_RETURN(const std::string meta_text, ReadFile((dir / "meta.json").string()));
  const nlohmann::json meta = nlohmann::json::parse(meta_text, nullptr, false);
  if (meta.is_discarded() || !meta.contains("version") || !meta.contains("items")) {
    return ParseError((dir / "meta.json").string() + ": malformed calibration metadata");
  }
  CalibrationVersion v;
  v.number = meta["version"].get<int>();
  v.dir = dir.string();
  v.created_unix_s = meta.value("created_unix_s", int64_t{0});
  for (const auto& [k, f] : meta["items"].items()) v.items[k] = f.get<std::string>();
  return std::optional<CalibrationVersion>(v);
}

Result<std::string> CalibrationStore::CurrentItemPath(const std::string& item) const {
  IDI_ASSIGN_OR_RETURN(const auto current, Current());
  if (!current || current->items.count(item) == 0) {
    return NotFound("no calibration of '" + item + "' in " + root_);
  }
  return (fs::path(current->dir) / current->items.at(item)).string();
}

Result<CalibrationVersion> CalibrationStore::Commit(const std::map<std::string, std::string>& updates,
                                                    int64_t now_unix_s,
                                                    const std::vector<std::string>& drop) {
  IDI_ASSIGN_OR_RETURN(const auto current, Current());
  CalibrationVersion next;
  // After every version there is, not only after the current one: a commit killed between its folder's
  // rename and the symlink's swap leaves a complete version that never became current, and the next
  // commit must not try to rename onto it (that fails, every time).
  next.number = (current ? current->number : 0) + 1;
  {
    std::error_code list_ec;
    for (const auto& e : fs::directory_iterator(fs::path(root_) / "versions", list_ec)) {
      const std::string name = e.path().filename().string();
      if (name.empty() || name.size() > 9 || name.find_first_not_of("0123456789") != std::string::npos) continue;
      next.number = std::max(next.number, std::stoi(name) + 1);
    }
    if (list_ec) return IoError((fs::path(root_) / "versions").string() + ": " + list_ec.message());
  }
  next.created_unix_s = now_unix_s;
  const fs::path versions = fs::path(root_) / "versions";
  const fs::path tmp = versions / (".tmp-" + VersionName(next.number));
  std::error_code ec;
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp, ec);
  if (ec) return IoError(tmp.string() + ": " + ec.message());
  // Carry over the items not being replaced.
  if (current) {
    for (const auto& [item, file] : current->items) {
      if (updates.count(item) != 0 || std::find(drop.begin(), drop.end(), item) != drop.end()) continue;
      IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile((fs::path(current->dir) / file).string()));
      IDI_RETURN_IF_ERROR(WriteFileAtomically((tmp / file).string(), text));
      next.items[item] = file;
    }
  }
  for (const auto& [item, text] : updates) {
    const std::string file = item + ".yaml";
    IDI_RETURN_IF_ERROR(WriteFileAtomically((tmp / file).string(), text));
    next.items[item] = file;
  }
  nlohmann::json meta;
  meta["version"] = next.number;
  meta["created_unix_s"] = now_unix_s;
  meta["items"] = next.items;
  IDI_RETURN_IF_ERROR(WriteFileAtomically((tmp / "meta.json").string(), meta.dump(2) + "\n"));
  const fs::path final_dir = versions / VersionName(next.number);
  fs::rename(tmp, final_dir, ec);
  if (ec) return IoError(final_dir.string() + ": " + ec.message());
  SyncDir(versions.string());
  // Swap the symlink atomically.
  const fs::path link_tmp = fs::path(root_) / "current.tmp";
  fs::remove(link_tmp, ec);
  fs::create_directory_symlink(fs::path("versions") / VersionName(next.number), link_tmp, ec);
  if (ec) return IoError(link_tmp.string() + ": " + ec.message());
  fs::rename(link_tmp, fs::path(root_) / "current", ec);
  if (ec) return IoError((fs::path(root_) / "current").string() + ": " + ec.message());
  SyncDir(root_);
  next.dir = final_dir.string();
  return next;
}

}  // namespace idi::workcell
