#include "command_registry.h"

namespace tagsfm {

static std::map<std::string, AddCommandFn>& Registry() {
  static std::map<std::string, AddCommandFn> registry;
  return registry;
}

bool RegisterCommand(const std::string& name, AddCommandFn add) {
  Registry()[name] = add;
  return true;
}

const std::map<std::string, AddCommandFn>& RegisteredCommands() { return Registry(); }

}  // namespace tagsfm
