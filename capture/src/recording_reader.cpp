#include <sys/stat.h>

#include <algorithm>
#include <fstream>

#include <opencv2/imgcodecs.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/file_util.h"

#include "tagsfm/capture/image_header.h"

namespace tagsfm {
namespace {

int ColumnIndex(const std::vector<std::string>& header, const std::string& name) {
  const auto it = std::find(header.begin(), header.end(), name);
  return it == header.end() ? -1 : static_cast<int>(it - header.begin());
}

// Decoders fill a cut-off JPEG or PGM with grey and only warn; the file's
// own end marker says whether it is whole.
bool LooksTruncated(const std::string& bytes) {
  const auto n = bytes.size();
  if (n >= 2 && static_cast<unsigned char>(bytes[0]) == 0xFF && static_cast<unsigned char>(bytes[1]) == 0xD8) {
    // JPEG: the end-of-image marker FF D9, allowing a little trailing padding.
    const size_t tail = std::min<size_t>(n, 64);
    return bytes.find("\xFF\xD9", n - tail) == std::string::npos;
  }
  if (n >= 8 && bytes.compare(1, 3, "PNG") == 0) {
    return bytes.find("IEND", n >= 16 ? n - 16 : 0) == std::string::npos;
  }
  return false;
}

}  // namespace

Result<RecordingReader> RecordingReader::Open(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) return MakeError(dir.string() + ": not a recording directory");
  RecordingReader reader;
  reader.dir_ = std::filesystem::absolute(dir);
  auto info = ReadRecordingYaml(reader.dir_ / "recording.yaml");
  if (!info) return info.error();
  reader.info_ = std::move(*info);

  const std::filesystem::path csv = reader.dir_ / "frames.csv";
  auto text = ReadFileToString(csv);
  if (!text) return text.error();
  const std::string& content = *text;
  size_t pos = 0;
  int line_number = 0;
  int col_frame = -1, col_time = -1, col_file = -1;
  while (pos < content.size()) {
    size_t end = content.find('\n', pos);
    const bool complete = end != std::string::npos;
    if (!complete) end = content.size();
    const std::string line = content.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    const std::string where = csv.string() + ":" + std::to_string(line_number) + ": ";
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const auto fields = SplitCsvLine(line);
    if (col_file < 0) {  // the first line that is not blank is the header
      col_frame = ColumnIndex(fields, "frame");
      col_time = ColumnIndex(fields, "timestamp_ns");
      col_file = ColumnIndex(fields, "file");
      if (col_frame < 0 || col_time < 0 || col_file < 0) {
        return MakeError(where + "header must have the columns frame,timestamp_ns,file");
      }
      continue;
    }
    FrameEntry entry;
    entry.csv_line = line_number;
    long long frame = 0, stamp = 0;
    const int needed = std::max({col_frame, col_time, col_file});
    std::string problem;
    if (static_cast<int>(fields.size()) <= needed) {
      problem = "expected at least " + std::to_string(needed + 1) + " fields, found " + std::to_string(fields.size());
    } else if (!ParseInt64(fields[col_frame], &frame)) {
      problem = "field 'frame' is not an integer: '" + fields[col_frame] + "'";
    } else if (!ParseInt64(fields[col_time], &stamp)) {
      problem = "field 'timestamp_ns' is not an integer: '" + fields[col_time] + "'";
    } else if (fields[col_file].empty()) {
      problem = "field 'file' is empty";
    }
    if (!problem.empty()) {
      // A recorder killed while writing leaves at most one partial last row.
      if (!complete) {
        reader.warnings_.push_back(where + "ignoring a partial last row (" + problem + ")");
        break;
      }
      return MakeError(where + problem);
    }
    entry.frame = frame;
    entry.timestamp_ns = stamp;
    const std::filesystem::path file(fields[col_file]);
    entry.file = file.is_absolute() ? file : reader.dir_ / file;
    reader.entries_.push_back(std::move(entry));
  }
  if (col_file < 0) return MakeError(csv.string() + ": empty file, expected the header frame,timestamp_ns,file");
  return reader;
}

Result<std::optional<TargetCornerMap>> RecordingReader::LoadTargetMap() const {
  if (info_.targets.map.empty()) return std::optional<TargetCornerMap>();
  const std::filesystem::path file(info_.targets.map);
  auto map = ReadTargetsCsv(file.is_absolute() ? file : dir_ / file);
  if (!map) return map.error();
  return std::optional<TargetCornerMap>(std::move(*map));
}

Result<Frame> LoadImageFrame(const std::filesystem::path& file, FrameId index, std::int64_t timestamp_ns) {
  const std::string where = file.string() + " (frame " + std::to_string(index) + "): ";
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) return MakeError(where + "file is missing");
  if (st.st_size == 0) return MakeError(where + "file is empty (0 bytes)");
  Frame frame;
  frame.index = index;
  frame.timestamp_ns = timestamp_ns;
  frame.source = file.string();
  // imread only warns on stderr for a truncated PNG/JPEG and may return a
  // partial image; reading the bytes and decoding them gives one answer.
  auto bytes = ReadFileToString(file);
  if (!bytes) return MakeError(where + "cannot read");
  // Frames are PNG (recorded), JPEG (photos) or PGM; their size is read
  // from the header and checked before the decoder allocates it. Other
  // formats' headers are not read here, so they are refused.
  const auto claimed = EncodedImageSize(reinterpret_cast<const std::uint8_t*>(bytes->data()), bytes->size());
  if (!claimed) return MakeError(where + "not a PNG, JPEG or PGM/PPM file (or its header is cut short)");
  if (ClaimsTooManyPixels(*claimed)) {
    return MakeError(where + "its header claims " + std::to_string(claimed->width) + "x" +
                     std::to_string(claimed->height) + " pixels, more than a frame can have (corrupt?)");
  }
  const cv::Mat buffer(1, static_cast<int>(bytes->size()), CV_8U, bytes->data());
  try {
    frame.image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    frame.image.release();
  }
  if (frame.image.empty()) return MakeError(where + "not a decodable image (corrupt or truncated?)");
  if (LooksTruncated(*bytes)) return MakeError(where + "image data is truncated");
  frame.gray = ToGray8(frame.image);
  return frame;
}

Result<Frame> RecordingReader::LoadFrame(size_t i) const {
  if (i >= entries_.size()) return MakeError(dir_.string() + ": no frame entry " + std::to_string(i));
  const FrameEntry& e = entries_[i];
  auto frame = LoadImageFrame(e.file, e.frame, e.timestamp_ns);
  if (!frame) {
    return MakeError((dir_ / "frames.csv").string() + ":" + std::to_string(e.csv_line) + ": " + frame.error().message);
  }
  return frame;
}

}  // namespace tagsfm
