#pragma once
// Running the tagsfm executable from a test, with its output in a log file.
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace tagsfm::testing {

// Runs `command` with stdout and stderr into `log`; its exit code, or -1
// when it did not exit normally (a crash).
inline int RunCommand(const std::string& command, const std::filesystem::path& log) {
  const int status = std::system((command + " > " + log.string() + " 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A whole text file; empty when it cannot be read.
inline std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace tagsfm::testing
