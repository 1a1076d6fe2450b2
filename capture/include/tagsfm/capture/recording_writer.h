#pragma once
// Writing a recording, crash-safe: each frame is written to a temporary file
// and renamed into place, then its frames.csv row is appended, flushed and
// fsync'd. A writer killed at any moment leaves a recording that reads back
// with every frame appended before the kill.
#include <filesystem>
#include <memory>

#include "tagsfm/capture/recording.h"

namespace tagsfm {

class RecordingWriter {
 public:
  // Creates REC/ (it must not exist, or be empty), writes recording.yaml.
  static Result<std::unique_ptr<RecordingWriter>> Create(const std::filesystem::path& dir, const RecordingInfo& info);
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  // Stores frame.image losslessly as PNG frames/NNNNNN.png; returns that
  // file's path (the writer owns the naming: callers never rebuild it).
  Result<std::filesystem::path> Append(const Frame& frame);

  const std::filesystem::path& dir() const { return dir_; }
  size_t frames_written() const { return frames_written_; }

 private:
  RecordingWriter(std::filesystem::path dir, int csv_fd) : dir_(std::move(dir)), csv_fd_(csv_fd) {}
  std::filesystem::path dir_;
  int csv_fd_ = -1;
  size_t frames_written_ = 0;
};

}  // namespace tagsfm
