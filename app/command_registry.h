#pragma once
// Subcommands of `tagsfm`. Each *_command.cpp defines a function that adds
// its subcommand to the CLI and registers it with a static
//   const bool kRegistered = tagsfm::RegisterCommand("name", &AddNameCommand);
// main() then adds every registered command, in name order.
#include <functional>
#include <map>
#include <string>

#include <CLI/CLI.hpp>

namespace tagsfm {

// Adds the subcommand to `app`; the subcommand's callback returns the process
// exit status through `exit_code`.
using AddCommandFn = void (*)(CLI::App& app, int& exit_code);

bool RegisterCommand(const std::string& name, AddCommandFn add);
const std::map<std::string, AddCommandFn>& RegisteredCommands();

}  // namespace tagsfm
