#include "vwe_vo/io/files.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <vector>

namespace vwe_vo {
namespace fs = std::filesystem;

bool fileExists(const std::string& path) {
  std::error_code ec;
  return fs::exists(path, ec);
}

void makeDirs(const std::string& path) {
  if (path.empty()) return;
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec && !fs::is_directory(path))
    throw std::runtime_error("cannot create directory " + path + ": " + ec.message());
}

namespace {

bool isConfigDir(const fs::path& dir) {
  std::error_code ec;
  return fs::exists(dir / "vwe_vo.yaml", ec) && fs::exists(dir / "davis346.yaml", ec);
}

bool namesVweVo(const fs::path& package_xml) {
  std::ifstream in(package_xml);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return text.find("<name>vwe_vo</name>") != std::string::npos;
}

}  // namespace

std::string defaultConfigDir() {
  std::vector<fs::path> candidates;
  if (const char* env = std::getenv("VWE_VO_CONFIG_DIR")) candidates.emplace_back(env);
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path dir = exe.parent_path();  // <space>/lib/vwe_vo
    candidates.push_back(dir / "../../share/vwe_vo/config");
  }
  if (const char* rpp = std::getenv("ROS_PACKAGE_PATH")) {
    std::stringstream ss(rpp);
    std::string entry;
    while (std::getline(ss, entry, ':')) {
      if (entry.empty()) continue;
      if (namesVweVo(fs::path(entry) / "package.xml"))
        candidates.push_back(fs::path(entry) / "config");
      candidates.push_back(fs::path(entry) / "vwe_vo/config");
    }
  }
  if (!ec) {
    // A catkin workspace: <ws>/devel/lib/vwe_vo/<exe> or <ws>/build/.../<exe>; walk up.
    for (fs::path p = exe.parent_path(); !p.empty() && p != p.root_path(); p = p.parent_path())
      candidates.push_back(p / "src/vwe_vo/config");
  }
  candidates.emplace_back("config");
  std::string looked;
  for (const fs::path& c : candidates) {
    if (!c.is_absolute() && c != "config") continue;
    if (isConfigDir(c)) return fs::weakly_canonical(c, ec).string();
    looked += "\n  " + c.string();
  }
  throw std::runtime_error(
      "cannot find vwe_vo's config folder (vwe_vo.yaml, davis346.yaml); set VWE_VO_CONFIG_DIR or "
      "pass the files explicitly. Looked in:" +
      looked);
}

}  // namespace vwe_vo
