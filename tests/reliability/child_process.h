#pragma once
// Starting the tagsfm executable as a child that a test can kill at any
// moment (std::system cannot), and a looped copy of a recording as a longer
// camera source.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "tagsfm/capture/recording.h"

extern char** environ;

namespace tagsfm::testing {

// Runs `args` (args[0] the executable) with stdout and stderr into `log`.
inline pid_t StartChild(const std::vector<std::string>& args, const std::filesystem::path& log) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid = -1;
  posix_spawn_file_actions_destroy(&actions);
  return pid;
}

struct ChildOutcome {
  bool killed = false;  // our SIGKILL ended it (false: it had exited by itself)
  int exit_code = -1;   // when it exited
};

// Waits `delay`, then SIGKILLs the child unless it has exited already.
inline ChildOutcome KillAfter(pid_t pid, std::chrono::microseconds delay) {
  const auto deadline = std::chrono::steady_clock::now() + delay;
  int status = 0;
  while (std::chrono::steady_clock::now() < deadline) {
    if (::waitpid(pid, &status, WNOHANG) == pid) return {false, WIFEXITED(status) ? WEXITSTATUS(status) : -1};
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, &status, 0);
  if (WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) return {true, -1};
  return {false, WIFEXITED(status) ? WEXITSTATUS(status) : -1};
}

inline ChildOutcome WaitChild(pid_t pid) {
  int status = 0;
  ::waitpid(pid, &status, 0);
  return {false, WIFEXITED(status) ? WEXITSTATUS(status) : -1};
}

// `source`'s frames played `loops` times over, as a recording in `dir`:
// recording.yaml copied, frames.csv naming the source's files by absolute
// path, with new frame numbers and timestamps 1/30 s apart.
inline void WriteLoopedRecording(const std::filesystem::path& source, int loops, const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(source / "recording.yaml", dir / "recording.yaml",
                             std::filesystem::copy_options::overwrite_existing);
  auto reader = RecordingReader::Open(source);
  std::ofstream csv(dir / "frames.csv");
  csv << "frame,timestamp_ns,file\n";
  long long frame = 0;
  for (int loop = 0; loop < loops; ++loop) {
    for (const auto& e : reader->entries()) {
      csv << frame << ',' << frame * 33333333LL << ',' << e.file.string() << '\n';
      ++frame;
    }
  }
}

}  // namespace tagsfm::testing
