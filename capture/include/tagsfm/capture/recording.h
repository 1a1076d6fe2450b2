#pragma once
// Reading a recording directory (see docs: interface.md):
//   REC/recording.yaml, REC/frames.csv, REC/frames/*, REC/targets.csv,
//   REC/ground_truth/.
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "tagsfm/capture/frame.h"
#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/result.h"

namespace tagsfm {

// One end of a scale bar: a tag's corner (0-3, libapriltag's order) or, with
// corner -1, its centre.
struct ScaleBarPoint {
  TagId tag = -1;
  int corner = -1;
};

// A certified distance between two target points (targets.scale_bars): the
// adjustment's scale then comes from it, not from the printed tag sizes.
struct ScaleBar {
  ScaleBarPoint a, b;
  double length_m = 0;
  double sigma_m = 0;  // its 1-sigma uncertainty (the certificate's)
};

struct TargetConfig {
  std::string family = "tag36h11";      // any libapriltag family name
  double size_m = 0.0;                  // edge of the tag's black square
  std::map<TagId, double> size_by_id;   // tags whose size differs
  std::string map;                      // optional targets.csv, relative to REC
  std::vector<ScaleBar> scale_bars;     // optional certified distances between target points

  double SizeOf(TagId id) const;
  Status Check() const;
};

// The family names libapriltag 3.3 knows.
const std::vector<std::string>& KnownTagFamilies();

struct RecordingInfo {
  std::optional<CameraModel> camera;  // absent: calibrate from the targets
  TargetConfig targets;
};

struct FrameEntry {
  FrameId frame = 0;
  std::int64_t timestamp_ns = 0;
  std::filesystem::path file;  // absolute, resolved against REC
  int csv_line = 0;            // line in frames.csv, for messages
};

// Parses recording.yaml; errors name the file and the field.
Result<RecordingInfo> ReadRecordingYaml(const std::filesystem::path& yaml_path);
std::string RecordingYamlText(const RecordingInfo& info);
// The same `camera:` and `targets:` blocks from any YAML file (the daemon's
// config), without recording.yaml's `format:` line.
Result<RecordingInfo> ReadCameraAndTargets(const std::filesystem::path& yaml_path);

class RecordingReader {
 public:
  // Checks recording.yaml and frames.csv (every row names an existing file);
  // images themselves are only read by LoadFrame.
  static Result<RecordingReader> Open(const std::filesystem::path& dir);

  const std::filesystem::path& dir() const { return dir_; }
  const RecordingInfo& info() const { return info_; }
  const std::vector<FrameEntry>& entries() const { return entries_; }
  // Things read past without failing, e.g. a last frames.csv row cut short
  // by a crash of the recorder.
  const std::vector<std::string>& warnings() const { return warnings_; }

  // The known target map named by recording.yaml, if any.
  Result<std::optional<TargetCornerMap>> LoadTargetMap() const;

  // Decodes entry i; a truncated, empty or undecodable image is an error
  // naming the file and frame, and the caller may skip it and go on.
  Result<Frame> LoadFrame(size_t i) const;

 private:
  std::filesystem::path dir_;
  RecordingInfo info_;
  std::vector<FrameEntry> entries_;
  std::vector<std::string> warnings_;
};

// Decodes one image file (PNG 8/16 bit, JPEG, PGM) into a Frame.
Result<Frame> LoadImageFrame(const std::filesystem::path& file, FrameId index, std::int64_t timestamp_ns);

}  // namespace tagsfm
