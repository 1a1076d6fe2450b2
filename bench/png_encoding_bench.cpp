// Recorded frames as PNG: tagsfm's writer (capture/png_encoding.h: Up
// filter, zlib's run-length strategy, level 1) against OpenCV 4.6's at the
// level the recorder used before (1, libpng's adaptive filters): time to
// encode a frame, to decode it (what every replay pays per frame), and the
// bytes a frame takes (counter `kb_per_frame`).
//
//   build/bench/png_encoding_bench [--benchmark_format=json] [DIR]
//
// DIR: a folder of frames (PNG or JPEG, read as grey); default the repo's
// recordings/box_small/frames (rendered, 640x480). Both writers run on the
// same first 20 frames.
#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/imgcodecs.hpp>

#include "tagsfm/capture/png_encoding.h"

namespace tagsfm {
namespace {

std::vector<cv::Mat>& Frames() {
  static std::vector<cv::Mat> frames;
  return frames;
}

std::vector<unsigned char> Encode(const cv::Mat& image, bool ours) {
  if (ours) return *EncodePng(image);
  std::vector<unsigned char> png;
  cv::imencode(".png", image, png, {cv::IMWRITE_PNG_COMPRESSION, 1});
  return png;
}

void BM_Encode(benchmark::State& state) {
  const bool ours = state.range(0) == 1;
  size_t bytes = 0, frames = 0;
  for (auto _ : state) {
    const cv::Mat& image = Frames()[frames % Frames().size()];
    const auto png = Encode(image, ours);
    bytes += png.size();
    ++frames;
  }
  state.SetLabel(ours ? "tagsfm" : "opencv");
  state.counters["kb_per_frame"] = double(bytes) / 1024.0 / double(std::max<size_t>(1, frames));
}

void BM_Decode(benchmark::State& state) {
  const bool ours = state.range(0) == 1;
  std::vector<std::vector<unsigned char>> encoded;
  for (const cv::Mat& image : Frames()) encoded.push_back(Encode(image, ours));
  size_t frames = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(cv::imdecode(encoded[frames % encoded.size()], cv::IMREAD_UNCHANGED));
    ++frames;
  }
  state.SetLabel(ours ? "tagsfm" : "opencv");
}

BENCHMARK(BM_Encode)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Decode)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace tagsfm

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  const std::filesystem::path dir =
      argc > 1 ? std::filesystem::path(argv[1]) : std::filesystem::path(TAGSFM_RECORDINGS_DIR) / "box_small" / "frames";
  std::vector<std::filesystem::path> files;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    const std::string ext = entry.path().extension().string();
    if (ext == ".png" || ext == ".jpg" || ext == ".JPG" || ext == ".jpeg") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  if (files.size() > 20) files.resize(20);
  for (const auto& f : files) {
    cv::Mat image = cv::imread(f.string(), cv::IMREAD_GRAYSCALE);
    if (!image.empty()) tagsfm::Frames().push_back(image);
  }
  if (tagsfm::Frames().empty()) {
    std::fprintf(stderr, "png_encoding_bench: no frames in %s\n", dir.c_str());
    return 1;
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
