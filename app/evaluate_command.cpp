// tagsfm evaluate OUT REC: scores a replay's results against the recording's
// ground truth; JSON on stdout (see eval/evaluation.h for what is measured).
#include <spdlog/spdlog.h>

#include <iostream>
#include <memory>

#include <CLI/CLI.hpp>

#include "command_registry.h"
#include "tagsfm/eval/evaluation.h"

namespace tagsfm {
namespace {

struct EvaluateArgs {
  std::string out;
  std::string rec;
};

void AddEvaluateCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<EvaluateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "evaluate", "compare a replay's results with the recording's ground_truth/ (paper eq. 1-3, targets, cloud); JSON");
  cmd->add_option("out", args->out, "the replay's output directory (poses.csv, targets.csv, cloud.ply, report.json)")
      ->required();
  cmd->add_option("rec", args->rec, "the recording with ground_truth/")->required();
  cmd->callback([args, &exit_code] {
    Result<std::string> json = eval::EvaluateDirectoriesJson(args->out, args->rec);
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
