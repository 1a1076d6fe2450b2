// tagsfm: capture-side 3D reconstruction with coded targets.
// Each subcommand is in its own *_command.cpp; see command_registry.h.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>

#include "command_registry.h"
#include "tagsfm/core/heap_reuse.h"

int main(int argc, char** argv) {
  tagsfm::KeepLargeBlocksForReuse();
  CLI::App app{"tagsfm: metric 3D reconstruction from AprilTag targets and natural features"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "tagsfm 0.1.0");
  int exit_code = 0;
  for (const auto& [name, add] : tagsfm::RegisteredCommands()) add(app, exit_code);
  // Messages, warnings and errors go to stderr; stdout carries results
  // (JSON of detect, evaluate, measure) that scripts read.
  spdlog::set_default_logger(spdlog::stderr_color_mt("tagsfm"));
  spdlog::set_pattern("%^%l%$: %v");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return exit_code;
}
