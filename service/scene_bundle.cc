// Scene bundles: building, checking and writing them (see scene_bundle.h).
#include "service/scene_bundle.h"

#include <pugixml.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <vector>

#include "absl/strings/str_split.h"
#include "render/scene_loader.h"

namespace irfarm {
namespace fs = std::filesystem;

namespace {

absl::StatusOr<std::string> ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(path + ": cannot open");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Where the scene loader finds the file an <include> names in a file read from inside the
// includes whose folders are `dirs` (innermost first, relative to the scene folder): next to
// each of them in turn, else in the scene folder (render/scene_loader.cc, Parser::ResolveFile).
// Parameter files are always relative to the scene folder.
std::string IncludePathOf(const fs::path& folder, const std::vector<fs::path>& dirs,
                          const std::string& name) {
  for (const fs::path& dir : dirs) {
    if (dir.empty()) continue;
    const fs::path near = (dir / name).lexically_normal();
    std::error_code ec;
    if (!near.empty() && *near.begin() != ".." && fs::is_regular_file(folder / near, ec))
      return near.string();
  }
  return fs::path(name).lexically_normal().string();
}

// Every file named under `node` (<string name="filename">, <include filename=...>) as a bundle
// path; included files are read and searched too, as deep as the loader follows them.
void CollectFilenames(const fs::path& folder, const std::vector<fs::path>& dirs,
                      const pugi::xml_node& node, int depth, std::set<std::string>* out) {
  for (const pugi::xml_node& c : node.children()) {
    const std::string tag = c.name();
    std::string value;
    if (tag == "string" && std::string(c.attribute("name").value()) == "filename")
      value = c.attribute("value").value();
    else if (tag == "include")
      value = c.attribute("filename").value();
    if (!value.empty() && value.find('$') == std::string::npos) {
      const std::string path = tag == "include" ? IncludePathOf(folder, dirs, value)
                                                : fs::path(value).lexically_normal().string();
      const bool first = out->insert(path).second;
      if (tag == "include" && first && depth + 1 < kMaxIncludeDepth) {
        absl::StatusOr<std::string> xml = ReadFile((folder / path).string());
        pugi::xml_document doc;
        if (xml.ok() && doc.load_buffer(xml->data(), xml->size())) {  // else the loader reports
          std::vector<fs::path> inner = {fs::path(path).parent_path()};
          inner.insert(inner.end(), dirs.begin(), dirs.end());
          CollectFilenames(folder, inner, doc, depth + 1, out);
        }
      }
    } else if (!value.empty()) {
      out->insert(value);  // a parameter: skipped below
    }
    CollectFilenames(folder, dirs, c, depth, out);
  }
}

}  // namespace

absl::Status CheckBundlePath(const std::string& path) {
  const auto bad = [&](const std::string& why) {
    return absl::InvalidArgumentError("bundle path '" + path + "' " + why);
  };
  if (path.empty()) return bad("is empty");
  if (path[0] == '/') return bad("is absolute (paths must stay inside the bundle)");
  if (path.find('\\') != std::string::npos || path.find('\0') != std::string::npos)
    return bad("contains a backslash or NUL");
  for (const absl::string_view part : absl::StrSplit(path, '/')) {
    if (part == "..") return bad("leaves the bundle ('..')");
    if (part.empty() || part == ".") return bad("has an empty or '.' component");
  }
  return absl::OkStatus();
}

size_t BundleBytes(const v1::SceneBundle& bundle) {
  size_t n = 0;
  for (const v1::BundleFile& f : bundle.files()) n += f.content().size() + f.path().size();
  return n;
}

absl::StatusOr<v1::SceneBundle> MakeBundle(const std::string& scene_path) {
  absl::StatusOr<std::string> xml = ReadFile(scene_path);
  if (!xml.ok()) return xml.status();
  v1::SceneBundle bundle;
  bundle.set_main_file("scene.xml");
  v1::BundleFile* main = bundle.add_files();
  main->set_path("scene.xml");
  main->set_content(*xml);
  pugi::xml_document doc;
  if (!doc.load_string(xml->c_str())) return bundle;  // the coordinator reports where it fails
  std::set<std::string> names;
  const fs::path folder = fs::path(scene_path).parent_path();
  CollectFilenames(folder, {}, doc, 0, &names);
  for (const std::string& name : names) {
    if (name.find('$') != std::string::npos) continue;  // a parameter: cannot resolve here
    absl::Status st = CheckBundlePath(fs::path(name).lexically_normal().string());
    if (!st.ok()) return st;
    absl::StatusOr<std::string> content = ReadFile((folder / name).string());
    if (!content.ok()) return content.status();
    v1::BundleFile* f = bundle.add_files();
    f->set_path(fs::path(name).lexically_normal().string());
    f->set_content(*content);
  }
  return bundle;
}

absl::StatusOr<std::string> WriteBundle(const v1::SceneBundle& bundle, const std::string& dir) {
  const std::string main = bundle.main_file().empty() ? "scene.xml" : bundle.main_file();
  absl::Status st = CheckBundlePath(main);
  if (!st.ok()) return st;
  if (bundle.files_size() > kMaxBundleFiles)
    return absl::InvalidArgumentError("bundle has " + std::to_string(bundle.files_size()) +
                                      " files, over the limit of " +
                                      std::to_string(kMaxBundleFiles));
  bool has_main = false;
  for (const v1::BundleFile& f : bundle.files()) {
    st = CheckBundlePath(f.path());
    if (!st.ok()) return st;
    has_main |= f.path() == main;
  }
  if (!has_main) return absl::InvalidArgumentError("bundle has no main file '" + main + "'");
  std::error_code ec;
  for (const v1::BundleFile& f : bundle.files()) {
    const fs::path p = fs::path(dir) / f.path();
    fs::create_directories(p.parent_path(), ec);
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out.write(f.content().data(), std::streamsize(f.content().size()));
    if (!out)
      return absl::InvalidArgumentError("bundle file '" + f.path() +
                                        "' cannot be written: its path is also a folder or a file "
                                        "of the bundle, or a name in it is too long");
  }
  return (fs::path(dir) / main).string();
}

}  // namespace irfarm
