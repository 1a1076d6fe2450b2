// COLMAP's text model (see colmap_model.h).
#include "tagsfm/eval/colmap_model.h"

#include <fstream>
#include <optional>
#include <sstream>

#include "tagsfm/core/file_util.h"

namespace tagsfm::eval {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> Tokens(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> tokens;
  std::string t;
  while (in >> t) tokens.push_back(t);
  return tokens;
}

bool IsBlank(const std::string& line) { return line.find_first_not_of(" \t\r") == std::string::npos; }

// Reads lines and says where it is, for messages.
class LineReader {
 public:
  explicit LineReader(const fs::path& path) : path_(path), in_(path) {}
  bool Opened() const { return static_cast<bool>(in_); }
  bool Next(std::string* line) {
    if (!std::getline(in_, *line)) return false;
    ++number_;
    if (!line->empty() && line->back() == '\r') line->pop_back();
    return true;
  }
  Error Fail(const std::string& what) const {
    return MakeError(path_.string() + ":" + std::to_string(number_) + ": " + what);
  }
  Error FailFile(const std::string& what) const { return MakeError(path_.string() + ": " + what); }

  // COLMAP's header says how many entries follow, e.g. "# Number of points: 12, mean ...";
  // remembered to tell a file cut short at a line boundary.
  void NoteDeclaredCount(const std::string& comment, const std::string& key) {
    const std::string marker = "# Number of " + key + ":";
    if (comment.rfind(marker, 0) != 0) return;
    std::string rest = comment.substr(marker.size());
    rest = rest.substr(0, rest.find(','));
    long long n = 0;
    const size_t first = rest.find_first_not_of(' ');
    if (first != std::string::npos && ParseInt64(rest.substr(first), &n)) declared_ = n;
  }
  Status CheckDeclaredCount(size_t found, const std::string& key) const {
    if (declared_ && *declared_ != static_cast<long long>(found)) {
      return FailFile("the header says " + std::to_string(*declared_) + " " + key + ", the file has " +
                      std::to_string(found) + " (cut short?)");
    }
    return Status::Ok();
  }

 private:
  fs::path path_;
  std::ifstream in_;
  int number_ = 0;
  std::optional<long long> declared_;
};

bool Number(const std::string& token, double* value) { return ParseDouble(token, value); }
bool Integer(const std::string& token, long long* value) { return ParseInt64(token, value); }

}  // namespace

bool IsColmapTextModel(const fs::path& dir) {
  std::error_code ec;
  return fs::is_regular_file(dir / "images.txt", ec) && fs::is_regular_file(dir / "points3D.txt", ec);
}

Result<std::map<long long, ColmapCamera>> ReadColmapCamerasTxt(const fs::path& path) {
  LineReader reader(path);
  if (!reader.Opened()) return reader.FailFile("cannot open");
  std::map<long long, ColmapCamera> cameras;
  std::string line;
  while (reader.Next(&line)) {
    if (IsBlank(line)) continue;
    if (line[0] == '#') {
      reader.NoteDeclaredCount(line, "cameras");
      continue;
    }
    const std::vector<std::string> t = Tokens(line);
    if (t.size() < 4) return reader.Fail("expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[], got " + std::to_string(t.size()) + " fields");
    ColmapCamera c;
    long long width = 0, height = 0;
    if (!Integer(t[0], &c.id)) return reader.Fail("CAMERA_ID '" + t[0] + "' is not an integer");
    c.model = t[1];
    if (!Integer(t[2], &width) || !Integer(t[3], &height) || width <= 0 || height <= 0) {
      return reader.Fail("WIDTH and HEIGHT must be positive integers");
    }
    c.width = static_cast<int>(width);
    c.height = static_cast<int>(height);
    for (size_t i = 4; i < t.size(); ++i) {
      double v = 0;
      if (!Number(t[i], &v)) return reader.Fail("parameter " + std::to_string(i - 3) + " '" + t[i] + "' is not a number");
      c.params.push_back(v);
    }
    if (!cameras.emplace(c.id, c).second) return reader.Fail("camera " + std::to_string(c.id) + " listed twice");
  }
  if (Status s = reader.CheckDeclaredCount(cameras.size(), "cameras"); !s) return s.error();
  return cameras;
}

Result<std::map<std::string, ColmapImage>> ReadColmapImagesTxt(const fs::path& path) {
  LineReader reader(path);
  if (!reader.Opened()) return reader.FailFile("cannot open");
  std::map<std::string, ColmapImage> images;
  std::map<long long, std::string> names_by_id;
  std::string line;
  while (reader.Next(&line)) {
    if (IsBlank(line)) continue;
    if (line[0] == '#') {
      reader.NoteDeclaredCount(line, "images");
      continue;
    }
    // First line of an image: IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME.
    const std::vector<std::string> t = Tokens(line);
    if (t.size() < 10) {
      return reader.Fail("expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, got " + std::to_string(t.size()) + " fields");
    }
    ColmapImage image;
    if (!Integer(t[0], &image.id)) return reader.Fail("IMAGE_ID '" + t[0] + "' is not an integer");
    double v[7];
    const char* names[] = {"QW", "QX", "QY", "QZ", "TX", "TY", "TZ"};
    for (int k = 0; k < 7; ++k) {
      if (!Number(t[static_cast<size_t>(k) + 1], &v[k])) return reader.Fail(std::string(names[k]) + " is not a number");
    }
    const Eigen::Quaterniond q(v[0], v[1], v[2], v[3]);
    if (q.norm() < 1e-9) return reader.Fail("the quaternion QW QX QY QZ is zero");
    image.cam_from_world = Rigid3d(q, Eigen::Vector3d(v[4], v[5], v[6]));
    if (!Integer(t[8], &image.camera_id)) return reader.Fail("CAMERA_ID '" + t[8] + "' is not an integer");
    // The name is the rest of the line (it may hold spaces).
    std::istringstream fields(line);
    std::string skip;
    for (int k = 0; k < 9; ++k) fields >> skip;
    std::getline(fields >> std::ws, image.name);
    while (!image.name.empty() && (image.name.back() == ' ' || image.name.back() == '\t')) image.name.pop_back();
    if (!names_by_id.emplace(image.id, image.name).second) return reader.Fail("image " + std::to_string(image.id) + " listed twice");
    if (images.count(image.name)) return reader.Fail("image name '" + image.name + "' listed twice");
    // Second line: POINTS2D[] as (X, Y, POINT3D_ID), possibly empty.
    if (!reader.Next(&line)) return reader.Fail("image " + std::to_string(image.id) + " has no POINTS2D line (file cut short?)");
    const std::vector<std::string> p = Tokens(line);
    if (p.size() % 3 != 0) return reader.Fail("POINTS2D must be triples X Y POINT3D_ID, got " + std::to_string(p.size()) + " values");
    for (size_t i = 0; i < p.size(); i += 3) {
      double x = 0, y = 0;
      long long point_id = 0;
      if (!Number(p[i], &x) || !Number(p[i + 1], &y) || !Integer(p[i + 2], &point_id)) {
        return reader.Fail("POINTS2D entry " + std::to_string(i / 3) + " is not X Y POINT3D_ID");
      }
      ++image.points2d;
      if (point_id != -1) ++image.observed_points2d;
    }
    images[image.name] = image;
  }
  if (Status s = reader.CheckDeclaredCount(images.size(), "images"); !s) return s.error();
  return images;
}

Result<std::vector<ColmapPoint>> ReadColmapPoints3DTxt(const fs::path& path) {
  LineReader reader(path);
  if (!reader.Opened()) return reader.FailFile("cannot open");
  std::vector<ColmapPoint> points;
  std::string line;
  while (reader.Next(&line)) {
    if (IsBlank(line)) continue;
    if (line[0] == '#') {
      reader.NoteDeclaredCount(line, "points");
      continue;
    }
    const std::vector<std::string> t = Tokens(line);
    if (t.size() < 8) return reader.Fail("expected POINT3D_ID X Y Z R G B ERROR TRACK[], got " + std::to_string(t.size()) + " fields");
    if ((t.size() - 8) % 2 != 0) return reader.Fail("TRACK must be pairs IMAGE_ID POINT2D_IDX (line cut short?)");
    ColmapPoint p;
    if (!Integer(t[0], &p.id)) return reader.Fail("POINT3D_ID '" + t[0] + "' is not an integer");
    for (int k = 0; k < 3; ++k) {
      if (!Number(t[static_cast<size_t>(k) + 1], &p.xyz[k])) return reader.Fail(std::string("XYZ").substr(static_cast<size_t>(k), 1) + " is not a number");
      long long c = 0;
      if (!Integer(t[static_cast<size_t>(k) + 4], &c) || c < 0 || c > 255) return reader.Fail("R G B must be integers 0-255");
      p.rgb[static_cast<size_t>(k)] = static_cast<int>(c);
    }
    if (!Number(t[7], &p.error_px) || p.error_px < 0) return reader.Fail("ERROR '" + t[7] + "' is not a non-negative number");
    for (size_t i = 8; i < t.size(); ++i) {
      long long v = 0;
      if (!Integer(t[i], &v)) return reader.Fail("TRACK entry '" + t[i] + "' is not an integer");
    }
    p.track_length = static_cast<int>((t.size() - 8) / 2);
    points.push_back(p);
  }
  if (Status s = reader.CheckDeclaredCount(points.size(), "points"); !s) return s.error();
  return points;
}

Result<ColmapModel> ReadColmapTextModel(const fs::path& dir) {
  ColmapModel model;
  std::error_code ec;
  // cameras.txt is only needed to check the images' CAMERA_IDs.
  const bool have_cameras = fs::is_regular_file(dir / "cameras.txt", ec);
  if (have_cameras) {
    Result<std::map<long long, ColmapCamera>> cameras = ReadColmapCamerasTxt(dir / "cameras.txt");
    if (!cameras) return cameras.error();
    model.cameras = std::move(*cameras);
  }
  Result<std::map<std::string, ColmapImage>> images = ReadColmapImagesTxt(dir / "images.txt");
  if (!images) return images.error();
  model.images_by_name = std::move(*images);
  if (have_cameras) {
    for (const auto& [name, image] : model.images_by_name) {
      if (!model.cameras.count(image.camera_id)) {
        return MakeError((dir / "images.txt").string() + ": image '" + name + "' names camera " +
                         std::to_string(image.camera_id) + ", which cameras.txt lacks");
      }
    }
  }
  Result<std::vector<ColmapPoint>> points = ReadColmapPoints3DTxt(dir / "points3D.txt");
  if (!points) return points.error();
  model.points = std::move(*points);
  return model;
}

ColmapFramePoses MatchImagesToFrames(const ColmapModel& model, const std::vector<FrameEntry>& frames,
                                     const fs::path& rec_dir) {
  const fs::path rec = fs::absolute(rec_dir).lexically_normal();
  std::map<std::string, FrameId> by_relative;
  std::map<std::string, std::vector<FrameId>> by_file_name;
  for (const FrameEntry& f : frames) {
    const fs::path file = fs::absolute(f.file).lexically_normal();
    by_relative[file.lexically_relative(rec).generic_string()] = f.frame;
    by_file_name[file.filename().string()].push_back(f.frame);
  }
  ColmapFramePoses out;
  for (const auto& [name, image] : model.images_by_name) {
    const fs::path path = fs::path(name).lexically_normal();
    std::optional<FrameId> frame;
    if (auto it = by_relative.find(path.generic_string()); it != by_relative.end()) {
      frame = it->second;
    } else if (auto jt = by_file_name.find(path.filename().string()); jt != by_file_name.end() && jt->second.size() == 1) {
      frame = jt->second.front();
    }
    if (frame) {
      out.cam_from_world[*frame] = image.cam_from_world;
    } else {
      out.unmatched_images.push_back(name);
    }
  }
  return out;
}

}  // namespace tagsfm::eval
