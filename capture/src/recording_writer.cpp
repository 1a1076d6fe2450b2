#include "tagsfm/capture/recording_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "tagsfm/capture/png_encoding.h"
#include "tagsfm/core/file_util.h"

namespace tagsfm {
namespace {

Status WriteAll(int fd, const std::string& text, const std::string& what) {
  size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      return MakeError(what + ": write failed (" + std::strerror(errno) + ")");
    }
    written += static_cast<size_t>(n);
  }
  return Status::Ok();
}

// Makes a rename inside `dir` durable across a power cut, not only a crash.
void SyncDirectory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

Result<std::unique_ptr<RecordingWriter>> RecordingWriter::Create(const std::filesystem::path& dir,
                                                                 const RecordingInfo& info) {
  std::error_code ec;
  if (std::filesystem::exists(dir, ec) && !std::filesystem::is_empty(dir, ec)) {
    return MakeError(dir.string() + ": already exists and is not empty; refusing to overwrite a recording");
  }
  if (info.camera) {
    if (Status s = info.camera->Check(); !s) return MakeError(dir.string() + ": " + s.error().message);
  }
  if (Status s = info.targets.Check(); !s) return MakeError(dir.string() + ": " + s.error().message);
  std::filesystem::create_directories(dir / "frames", ec);
  if (ec) return MakeError(dir.string() + ": cannot create (" + ec.message() + ")");
  if (Status s = WriteFileAtomically(dir / "recording.yaml", RecordingYamlText(info)); !s) return s.error();

  const std::filesystem::path csv = dir / "frames.csv";
  const int fd = ::open(csv.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) return MakeError(csv.string() + ": cannot create (" + std::strerror(errno) + ")");
  if (Status s = WriteAll(fd, "frame,timestamp_ns,file\n", csv.string()); !s) {
    ::close(fd);
    return s.error();
  }
  ::fsync(fd);
  SyncDirectory(dir);
  return std::unique_ptr<RecordingWriter>(new RecordingWriter(dir, fd));
}

RecordingWriter::~RecordingWriter() {
  if (csv_fd_ >= 0) ::close(csv_fd_);
}

Result<std::filesystem::path> RecordingWriter::Append(const Frame& frame) {
  if (frame.image.empty()) return MakeError(dir_.string() + ": frame " + std::to_string(frame.index) + " has no image");
  char name[64];
  std::snprintf(name, sizeof name, "frames/%06lld.png", static_cast<long long>(frame.index));
  // Lossless, and fast to write and to read back (png_encoding.h): the
  // recording must keep up with the camera, the replay run faster than it.
  Result<std::vector<unsigned char>> png = EncodePng(frame.image);
  if (!png) {
    return MakeError(dir_.string() + ": frame " + std::to_string(frame.index) + " cannot be recorded (" +
                     png.error().message + ")");
  }
  if (Status s = WriteFileAtomically(dir_ / name, *png); !s) return s.error();
  SyncDirectory(dir_ / "frames");
  // The row goes in only once its image is in place, in one write() so a
  // crash leaves at most one partial last row, which the reader skips.
  const std::string row = std::to_string(frame.index) + "," + std::to_string(frame.timestamp_ns) + "," + name + "\n";
  if (Status s = WriteAll(csv_fd_, row, (dir_ / "frames.csv").string()); !s) return s.error();
  if (::fsync(csv_fd_) != 0) return MakeError((dir_ / "frames.csv").string() + ": fsync failed");
  ++frames_written_;
  return dir_ / name;
}

}  // namespace tagsfm
