// tagsfm measure OUT A B: the distance between two points of a replay's
// result, with its standard deviation: targets (tag centre or corner) from
// the final adjustment's covariance, feature points ("pID", ids as in
// features.csv and colmap/points3D.txt) from their triangulation's; or
// with --all-pairs every pair of targets.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "replay_support.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/export/feature_points_csv.h"
#include "tagsfm/export/target_covariance_csv.h"
#include "tagsfm/recon/measurement.h"

namespace tagsfm {
namespace {

struct MeasureArgs {
  std::string out;
  std::string a, b;
  bool json = false;
  bool all_pairs = false;
};

int Print(const MeasureArgs& args, const Measurement& measurement);

bool IsFeatureRef(const std::string& text) { return !text.empty() && (text[0] == 'p' || text[0] == 'P'); }

// A measurement with at least one feature point. The feature's covariance
// is its triangulation's (the poses and a target taken as exact: both are
// known far better than a point from a few rays); the scale's own
// uncertainty (`scale_sigma_rel`, what the images cannot see) adds
// scale_sigma_rel * distance, as for targets.
Result<Measurement> MeasureWithFeatures(const std::filesystem::path& dir, const std::string& a_text,
                                        const std::string& b_text, double scale_sigma_rel) {
  auto features = ReadFeaturePointsCsv(dir / "features.csv");
  if (!features) return features.error();
  std::optional<TargetCornerMap> targets;
  auto locate = [&](const std::string& text, Eigen::Vector3d* position, Eigen::Matrix3d* covariance) -> Status {
    if (IsFeatureRef(text)) {
      long long id = 0;
      try {
        size_t used = 0;
        id = std::stoll(text.substr(1), &used);
        if (used != text.size() - 1) throw std::invalid_argument(text);
      } catch (const std::exception&) {
        return MakeError("'" + text + "' is not a feature point (pID, e.g. p100000012)");
      }
      auto it = features->find(id);
      if (it == features->end()) return MakeError((dir / "features.csv").string() + ": no feature point " + text.substr(1));
      *position = it->second.position;
      *covariance = it->second.covariance;
      return Status::Ok();
    }
    auto ref = ParseTargetPointRef(text);
    if (!ref) return ref.error();
    if (!targets) {
      auto read = ReadTargetsCsv(dir / "targets.csv");
      if (!read) return read.error();
      targets = std::move(*read);
    }
    auto it = targets->find(ref->tag);
    if (it == targets->end()) return MakeError((dir / "targets.csv").string() + ": no target " + std::to_string(ref->tag));
    *position = ref->PointOn(it->second);
    covariance->setZero();
    return Status::Ok();
  };
  Measurement m;
  Eigen::Matrix3d ca, cb;
  if (Status s = locate(a_text, &m.a, &ca); !s) return s.error();
  if (Status s = locate(b_text, &m.b, &cb); !s) return s.error();
  m.distance_m = (m.a - m.b).norm();
  if (m.distance_m > 0) {
    const Eigen::Vector3d u = (m.a - m.b) / m.distance_m;
    const double scale_sigma_m = scale_sigma_rel * m.distance_m;
    m.sigma_m = std::sqrt(std::max(0.0, u.dot((ca + cb) * u)) + scale_sigma_m * scale_sigma_m);
  }
  m.note = "sigma from the feature points' triangulation and the scale's sigma; poses and targets taken as exact";
  return m;
}

Result<std::optional<TagCovariance>> ReadOptionalCovariance(const std::filesystem::path& dir) {
  if (!std::filesystem::exists(dir / "targets_cov.csv")) return std::optional<TagCovariance>();
  auto cov = ReadTargetCovariance(dir / "targets_cov.csv");
  if (!cov) return cov.error();
  return std::optional<TagCovariance>(std::move(*cov));
}

// report.json's scale.sigma_rel (the scale's own uncertainty: print
// tolerance or scale bars), 0 for results written before it was reported.
double ScaleSigmaRel(const std::filesystem::path& dir) {
  auto text = ReadFileToString(dir / "report.json");
  if (!text) return 0.0;
  const nlohmann::json report = nlohmann::json::parse(*text, nullptr, /*allow_exceptions=*/false);
  if (!report.is_object() || !report.contains("scale") || !report["scale"].is_object() || !report["scale"]["sigma_rel"].is_number()) return 0.0;
  return report["scale"]["sigma_rel"].get<double>();
}

// --all-pairs: every pair of targets centre to centre, shortest first (the
// test lengths of a VDI/VDE 2634-1 style check, without truth).
int RunAllPairs(const MeasureArgs& args) {
  const std::filesystem::path dir(args.out);
  auto targets = ReadTargetsCsv(dir / "targets.csv");
  if (!targets) return Fail(targets.error(), 1);
  auto covariance = ReadOptionalCovariance(dir);
  if (!covariance) return Fail(covariance.error(), 1);
  const std::vector<TagPairMeasurement> pairs = MeasureAllTagPairs(*targets, *covariance, ScaleSigmaRel(dir));
  if (args.json) {
    nlohmann::json j = nlohmann::json::array();
    for (const TagPairMeasurement& p : pairs) {
      const Measurement& m = p.measurement;
      j.push_back({{"a", p.a}, {"b", p.b}, {"distance_m", m.distance_m},
                   {"sigma_m", m.sigma_m ? nlohmann::json(*m.sigma_m) : nlohmann::json(nullptr)}});
    }
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("tag_a,tag_b,distance_m,sigma_m\n");
  for (const TagPairMeasurement& p : pairs) {
    const Measurement& m = p.measurement;
    std::printf("%d,%d,%.6f,%s\n", p.a, p.b, m.distance_m, m.sigma_m ? fmt::format("{:.6f}", *m.sigma_m).c_str() : "");
  }
  return 0;
}

int RunMeasure(const MeasureArgs& args) {
  const std::filesystem::path dir(args.out);
  if (args.all_pairs) return RunAllPairs(args);
  if (args.a.empty() || args.b.empty()) {
    spdlog::error("measure needs two points A B, or --all-pairs");
    return 2;
  }
  if (IsFeatureRef(args.a) || IsFeatureRef(args.b)) {
    auto m = MeasureWithFeatures(dir, args.a, args.b, ScaleSigmaRel(dir));
    if (!m) {
      spdlog::error("{}", m.error().message);
      return 1;
    }
    return Print(args, *m);
  }
  auto a = ParseTargetPointRef(args.a);
  auto b = ParseTargetPointRef(args.b);
  if (!a || !b) {
    spdlog::error("{}", (!a ? a.error() : b.error()).message);
    return 2;
  }
  auto targets = ReadTargetsCsv(dir / "targets.csv");
  if (!targets) {
    spdlog::error("{}", targets.error().message);
    return 1;
  }
  auto covariance = ReadOptionalCovariance(dir);
  if (!covariance) {
    spdlog::error("{}", covariance.error().message);
    return 1;
  }
  auto m = MeasureDistance(*targets, *covariance, *a, *b, ScaleSigmaRel(dir));
  if (!m) {
    spdlog::error("{}: {}", (dir / "targets.csv").string(), m.error().message);
    return 1;
  }
  return Print(args, *m);
}

int Print(const MeasureArgs& args, const Measurement& measurement) {
  const Measurement* m = &measurement;
  if (args.json) {
    nlohmann::json j = {{"a", args.a}, {"b", args.b}, {"distance_m", m->distance_m}};
    j["sigma_m"] = m->sigma_m ? nlohmann::json(*m->sigma_m) : nlohmann::json(nullptr);
    if (!m->note.empty()) j["note"] = m->note;
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("%s to %s: %.6f m", args.a.c_str(), args.b.c_str(), m->distance_m);
    if (m->sigma_m) std::printf(" +- %.6f m (1 sigma)", *m->sigma_m);
    std::printf("\n");
    if (!m->note.empty()) std::printf("note: %s\n", m->note.c_str());
  }
  return 0;
}

void AddMeasureCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<MeasureArgs>();
  CLI::App* cmd = app.add_subcommand("measure", "distance between two points of a result (targets or feature points), with its standard deviation");
  cmd->add_option("out", args->out, "a replay's output folder (targets.csv, targets_cov.csv, features.csv)")->required();
  cmd->add_option("a", args->a, "a point: tag id (its centre), ID:CORNER, or a feature point pID (features.csv)");
  cmd->add_option("b", args->b, "the other target");
  cmd->add_flag("--all-pairs", args->all_pairs,
                "every pair of targets centre to centre with its sigma, shortest first (CSV, or JSON with --json)");
  cmd->add_flag("--json", args->json, "print JSON");
  cmd->callback([args, &exit_code] { exit_code = RunMeasure(*args); });
}

const bool kRegistered = RegisterCommand("measure", &AddMeasureCommand);

}  // namespace
}  // namespace tagsfm
