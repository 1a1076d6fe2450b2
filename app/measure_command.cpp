// tagsfm measure OUT A B: the distance between two targets of a replay's
// result, with its standard deviation from the final adjustment.
#include <cstdio>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "tagsfm/recon/measurement.h"
#include "tagsfm/recon/result_writer.h"

namespace tagsfm {
namespace {

struct MeasureArgs {
  std::string out;
  std::string a, b;
  bool json = false;
};

int RunMeasure(const MeasureArgs& args) {
  const std::filesystem::path dir(args.out);
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
  std::optional<TagCovariance> covariance;
  if (std::filesystem::exists(dir / "targets_cov.csv")) {
    auto cov = ReadTargetCovariance(dir / "targets_cov.csv");
    if (!cov) {
      spdlog::error("{}", cov.error().message);
      return 1;
    }
    covariance = std::move(*cov);
  }
  auto m = MeasureDistance(*targets, covariance, *a, *b);
  if (!m) {
    spdlog::error("{}: {}", (dir / "targets.csv").string(), m.error().message);
    return 1;
  }
  if (args.json) {
    nlohmann::json j = {{"a", args.a}, {"b", args.b}, {"distance_m", m->distance_m}};
    j["sigma_m"] = m->sigma_m ? nlohmann::json(*m->sigma_m) : nlohmann::json(nullptr);
    if (!m->note.empty()) j["note"] = m->note;
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("%s to %s: %.6f m", a->ToString().c_str(), b->ToString().c_str(), m->distance_m);
    if (m->sigma_m) std::printf(" +- %.6f m (1 sigma)", *m->sigma_m);
    std::printf("\n");
    if (!m->note.empty()) std::printf("note: %s\n", m->note.c_str());
  }
  return 0;
}

void AddMeasureCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<MeasureArgs>();
  CLI::App* cmd = app.add_subcommand("measure", "distance between two targets of a result, with its standard deviation");
  cmd->add_option("out", args->out, "a replay's output folder (targets.csv, targets_cov.csv)")->required();
  cmd->add_option("a", args->a, "a target: tag id (its centre) or ID:CORNER")->required();
  cmd->add_option("b", args->b, "the other target")->required();
  cmd->add_flag("--json", args->json, "print JSON");
  cmd->callback([args, &exit_code] { exit_code = RunMeasure(*args); });
}

const bool kRegistered = RegisterCommand("measure", &AddMeasureCommand);

}  // namespace
}  // namespace tagsfm
