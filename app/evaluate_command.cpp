// tagsfm evaluate OUT REC: scores a replay's results (or a COLMAP text model)
// against the recording's ground truth; JSON on stdout (see
// eval/evaluation.h for what is measured), or with --summary one
// tab-separated line for scripts (bench/compare_colmap.sh).
#include <spdlog/spdlog.h>

#include <iostream>
#include <memory>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "command_registry.h"
#include "tagsfm/eval/evaluation.h"

namespace tagsfm {
namespace {

struct EvaluateArgs {
  std::string out;
  std::string rec;
  std::string summary;  // a variant name, or empty for the JSON
};

std::string Fixed(const nlohmann::json& value, int digits, double factor = 1.0) {
  if (!value.is_number()) return "n/a";
  return fmt::format("{:.{}f}", value.get<double>() * factor, digits);
}

// registered, ground-truth frames, feature points, mean reprojection (px),
// % within 1/2/5 mm in VARIANT, scale error of the similarity fit (ppm).
Result<std::string> SummaryLine(const std::string& json_text, const std::string& variant) {
  const nlohmann::json e = nlohmann::json::parse(json_text);
  if (!e.contains(variant)) return MakeError("--summary " + variant + ": not a variant (as_is, rigid, similarity)");
  const nlohmann::json& v = e[variant];
  const nlohmann::json none;
  const nlohmann::json& shares = v.is_object() && v["feature_points"].is_object() ? v["feature_points"] : none;
  const nlohmann::json& similarity = e["alignment"].contains("similarity") ? e["alignment"]["similarity"] : none;
  const auto share = [&](const char* key) { return shares.is_object() ? Fixed(shares[key], 1, 100.0) : "n/a"; };
  return fmt::format("{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\n", e["frames"]["registered"].get<int>(),
                     e["frames"]["ground_truth"].get<int>(), e["feature_points"]["count"].get<int>(),
                     Fixed(e["feature_points"]["mean_reprojection_px"], 3), share("within_1mm"), share("within_2mm"),
                     share("within_5mm"),
                     similarity.is_object() ? Fixed(similarity["scale_error_ppm"], 0) : std::string("n/a"));
}

void AddEvaluateCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<EvaluateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "evaluate", "compare a replay's results with the recording's ground_truth/ (paper eq. 1-3, targets, cloud); JSON");
  cmd->add_option("out", args->out,
                  "the replay's output directory (poses.csv, targets.csv, cloud.ply, features.csv, report.json), "
                  "or a COLMAP text model (images.txt, points3D.txt; images matched to frames.csv by file name)")
      ->required();
  cmd->add_option("rec", args->rec, "the recording with ground_truth/")->required();
  cmd->add_option("--summary", args->summary,
                  "instead of the JSON, one tab-separated line for VARIANT (as_is, rigid, similarity): registered "
                  "frames, ground-truth frames, feature points, their mean reprojection error (px), % of them within "
                  "1, 2, 5 mm of the true surfaces, scale error of the similarity fit (ppm); n/a where absent")
      ->check(CLI::IsMember({"as_is", "rigid", "similarity"}));
  cmd->callback([args, &exit_code] {
    Result<std::string> json = eval::EvaluateDirectoriesJson(args->out, args->rec);
    if (json && !args->summary.empty()) json = SummaryLine(*json, args->summary);
    if (!json) {
      spdlog::error("{}", json.error().message);
      exit_code = 1;
      return;
    }
    std::cout << *json;
    exit_code = 0;
  });
}

const bool kRegistered = RegisterCommand("evaluate", &AddEvaluateCommand);

}  // namespace
}  // namespace tagsfm
