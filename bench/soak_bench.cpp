// Soak: the pipeline on a long sequence (a small recording looped through a
// generated frames.csv), frame by frame as `replay` runs it, recording the
// resident memory every 100 frames and each frame's processing time
// (Pipeline::Process, the image decode excluded). Prints JSON: the memory
// curve, per-1000-frame latency percentiles, and the two figures the soak
// is judged by (docs/reliability.md):
//   memory_growth:  RSS at the end over RSS at the end of warm-up
//   p95_ratio:      p95 latency of the last 1000 frames over the first 1000 after warm-up
//   soak_bench --source recordings/box_small --frames 20000 --work DIR [--check MEM LAT]
// With --check, exits 1 when a figure exceeds its limit (1 + MEM, 1 + LAT).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tagsfm/core/heap_reuse.h"
#include "tagsfm/pipeline/drivers.h"
#include "tagsfm/pipeline/target_map.h"

namespace tagsfm {
namespace {

struct SoakArgs {
  std::string source;
  std::string work;
  long long frames = 20000;
  long long warmup = 2000;
  double check_memory = -1, check_latency = -1;
};

double CurrentRssMb() {
  std::ifstream statm("/proc/self/statm");
  long long pages = 0, resident = 0;
  statm >> pages >> resident;
  return static_cast<double>(resident) * static_cast<double>(::sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

// `source`'s frames looped to `frames` rows, file paths absolute, 30 fps.
Status WriteLoopedRecording(const std::filesystem::path& source, long long frames, const std::filesystem::path& dir) {
  auto reader = RecordingReader::Open(source);
  if (!reader) return reader.error();
  if (reader->entries().empty()) return MakeError(source.string() + ": no frames");
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(source / "recording.yaml", dir / "recording.yaml",
                             std::filesystem::copy_options::overwrite_existing);
  std::ofstream csv(dir / "frames.csv");
  csv << "frame,timestamp_ns,file\n";
  const auto& entries = reader->entries();
  for (long long i = 0; i < frames; ++i) {
    csv << i << ',' << i * 33333333LL << ',' << entries[i % entries.size()].file.string() << '\n';
  }
  return csv ? Status::Ok() : MakeError((dir / "frames.csv").string() + ": cannot write");
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

int RunSoak(const SoakArgs& args) {
  const std::filesystem::path rec = std::filesystem::path(args.work) / "looped";
  if (Status s = WriteLoopedRecording(args.source, args.frames, rec); !s) {
    std::fprintf(stderr, "soak: %s\n", s.error().message.c_str());
    return 2;
  }
  auto reader = RecordingReader::Open(rec);
  if (!reader) return std::fprintf(stderr, "soak: %s\n", reader.error().message.c_str()), 2;
  auto map = ResolveTargetMap(reader->info(), reader->dir(), "");
  if (!map) return std::fprintf(stderr, "soak: %s\n", map.error().message.c_str()), 2;
  PipelineOptions options;
  options.live_feedback = true;  // as the daemon runs
  auto pipeline = Pipeline::Create({reader->info(), *map, RecordingFrameLoader(*reader), "recording.yaml"}, options);
  if (!pipeline) return std::fprintf(stderr, "soak: %s\n", pipeline.error().message.c_str()), 2;

  std::vector<double> latency_ms;
  nlohmann::json memory = nlohmann::json::array();
  for (size_t i = 0; i < reader->entries().size(); ++i) {
    auto frame = reader->LoadFrame(i);
    if (!frame) return std::fprintf(stderr, "soak: %s\n", frame.error().message.c_str()), 1;
    const auto t0 = std::chrono::steady_clock::now();
    (void)(*pipeline)->Process(*frame);
    latency_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (i % 100 == 99) memory.push_back({{"frame", i + 1}, {"rss_mb", CurrentRssMb()}});
  }
  (void)(*pipeline)->TakeWarnings();

  nlohmann::json blocks = nlohmann::json::array();
  for (size_t b = 0; b + 1000 <= latency_ms.size(); b += 1000) {
    const std::vector<double> block(latency_ms.begin() + static_cast<long>(b), latency_ms.begin() + static_cast<long>(b + 1000));
    blocks.push_back({{"first_frame", b}, {"p50_ms", Percentile(block, 0.5)}, {"p95_ms", Percentile(block, 0.95)}});
  }
  const size_t warm = static_cast<size_t>(args.warmup);
  const size_t n = latency_ms.size();
  nlohmann::json out{{"frames", n}, {"warmup_frames", warm}, {"memory", memory}, {"latency_blocks", blocks}};
  if (n >= warm + 2000 && !memory.empty()) {
    double rss_warm = 0;
    for (const auto& m : memory) {
      if (m["frame"].get<size_t>() <= warm) rss_warm = m["rss_mb"].get<double>();
    }
    const double rss_end = memory.back()["rss_mb"].get<double>();
    const std::vector<double> first(latency_ms.begin() + static_cast<long>(warm), latency_ms.begin() + static_cast<long>(warm + 1000));
    const std::vector<double> last(latency_ms.end() - 1000, latency_ms.end());
    out["rss_after_warmup_mb"] = rss_warm;
    out["rss_end_mb"] = rss_end;
    out["memory_growth"] = rss_end / rss_warm;
    out["p95_first_ms"] = Percentile(first, 0.95);
    out["p95_last_ms"] = Percentile(last, 0.95);
    out["p95_ratio"] = Percentile(last, 0.95) / Percentile(first, 0.95);
  }
  std::printf("%s\n", out.dump(1).c_str());
  if (args.check_memory >= 0) {
    if (!out.contains("memory_growth")) return std::fprintf(stderr, "soak: too few frames to judge\n"), 1;
    const bool memory_ok = out["memory_growth"].get<double>() <= 1.0 + args.check_memory;
    const bool latency_ok = out["p95_ratio"].get<double>() <= 1.0 + args.check_latency;
    std::fprintf(stderr, "soak: memory x%.3f (limit %.2f), p95 latency x%.3f (limit %.2f): %s\n",
                 out["memory_growth"].get<double>(), 1.0 + args.check_memory, out["p95_ratio"].get<double>(),
                 1.0 + args.check_latency, memory_ok && latency_ok ? "ok" : "FAILED");
    if (!memory_ok || !latency_ok) return 1;
  }
  return 0;
}

}  // namespace
}  // namespace tagsfm

int main(int argc, char** argv) {
  tagsfm::KeepLargeBlocksForReuse();  // as the tagsfm executable, whose daemon this measures
  tagsfm::SoakArgs args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--source" && has_value) args.source = argv[++i];
    else if (a == "--work" && has_value) args.work = argv[++i];
    else if (a == "--frames" && has_value) args.frames = std::atoll(argv[++i]);
    else if (a == "--warmup" && has_value) args.warmup = std::atoll(argv[++i]);
    else if (a == "--check" && i + 2 < argc) {
      args.check_memory = std::atof(argv[++i]);
      args.check_latency = std::atof(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: soak_bench --source REC --work DIR [--frames N] [--warmup N] [--check MEM LAT]\n");
      return 2;
    }
  }
  if (args.source.empty() || args.work.empty()) {
    std::fprintf(stderr, "soak_bench: --source and --work are required\n");
    return 2;
  }
  return tagsfm::RunSoak(args);
}
