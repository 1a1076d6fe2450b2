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
#include "tagsfm/analysis/length_error_plot.h"
#include "tagsfm/eval/evaluation.h"

namespace tagsfm {
namespace {

struct EvaluateArgs {
  std::string out;
  std::string rec;
  std::string summary;      // a variant name, or empty for the JSON
  std::string length_plot;  // PNG of the length errors, or empty
};

// The JSON's "lengths" back as values, for the plot.
eval::LengthErrors LengthsFromJson(const nlohmann::json& lengths) {
  eval::LengthErrors out;
  if (!lengths.is_object()) return out;
  for (const nlohmann::json& p : lengths["pairs"]) {
    eval::LengthError e;
    e.a = p["a"].get<TagId>();
    e.b = p["b"].get<TagId>();
    e.true_length_m = p["true_length_m"].get<double>();
    e.measured_length_m = p["measured_length_m"].get<double>();
    e.error_m = p["error_m"].get<double>();
    if (p["sigma_m"].is_number()) e.sigma_m = p["sigma_m"].get<double>();
    out.pairs.push_back(e);
  }
  return out;
}

Status WriteLengthPlot(const std::string& json_text, const EvaluateArgs& args) {
  const eval::LengthErrors lengths = LengthsFromJson(nlohmann::json::parse(json_text)["lengths"]);
  if (lengths.pairs.empty()) return MakeError("--length-plot: no tag pairs common to " + args.out + " and the truth");
  auto outcome = analysis::RenderLengthErrorPlot(lengths, "length error: " + args.out, args.length_plot);
  if (!outcome) return outcome.error();
  if (*outcome == analysis::PlotOutcome::kGnuplotMissing) spdlog::warn("gnuplot not found: only the script was written");
  return Status::Ok();
}

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
  cmd->add_option("--length-plot", args->length_plot,
                  "also draw the length-measurement error of every tag pair against its length (VDI/VDE 2634-1 "
                  "style) into this PNG (with its gnuplot script beside it)");
  cmd->callback([args, &exit_code] {
    Result<std::string> json = eval::EvaluateDirectoriesJson(args->out, args->rec);
    if (json && !args->length_plot.empty()) {
      if (Status s = WriteLengthPlot(*json, *args); !s) json = s.error();
    }
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
