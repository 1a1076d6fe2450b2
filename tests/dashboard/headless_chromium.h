#pragma once
// Headless Chromium driven through the DevTools protocol on a pipe
// (--remote-debugging-pipe: commands go to the browser's fd 3, replies come
// from its fd 4, each message JSON ended by a NUL byte). No WebSocket client
// and no script language needed: what the browser test uses to read the
// dashboard's DOM while it updates, and to take a screenshot.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

extern char** environ;

namespace tagsfm::testing {

// Debian's launcher (or any `chromium` on PATH); empty when there is none.
inline std::string FindChromium() {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  for (size_t start = 0; start <= dirs.size();) {
    const size_t end = std::min(dirs.find(':', start), dirs.size());
    const auto candidate = std::filesystem::path(dirs.substr(start, end - start)) / "chromium";
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    start = end + 1;
  }
  return "";
}

inline std::string DecodeBase64(const std::string& text) {
  std::string out;
  unsigned value = 0;
  int bits = 0;
  for (char c : text) {
    int v;
    if (c >= 'A' && c <= 'Z') v = c - 'A';
    else if (c >= 'a' && c <= 'z') v = c - 'a' + 26;
    else if (c >= '0' && c <= '9') v = c - '0' + 52;
    else if (c == '+') v = 62;
    else if (c == '/') v = 63;
    else continue;  // padding
    value = (value << 6) | static_cast<unsigned>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<char>((value >> bits) & 0xff));
    }
  }
  return out;
}

class HeadlessChromium {
 public:
  // Starts the browser with a window of width x height and its own profile
  // in `profile_dir`; its messages go to `log`. Null when it cannot start.
  static std::unique_ptr<HeadlessChromium> Launch(const std::string& exe, int width, int height,
                                                  const std::filesystem::path& profile_dir,
                                                  const std::filesystem::path& log) {
    int to_browser[2], from_browser[2];
    if (::pipe2(to_browser, O_CLOEXEC) != 0) return nullptr;
    if (::pipe2(from_browser, O_CLOEXEC) != 0) return nullptr;
    // Above 3 and 4 first, so that placing one end cannot overwrite the other.
    for (int* fd : {&to_browser[0], &from_browser[1]}) {
      const int high = ::fcntl(*fd, F_DUPFD_CLOEXEC, 10);
      ::close(*fd);
      *fd = high;
    }
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    posix_spawn_file_actions_adddup2(&actions, to_browser[0], 3);
    posix_spawn_file_actions_adddup2(&actions, from_browser[1], 4);
    std::vector<std::string> args = {exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                                     "--hide-scrollbars", "--remote-debugging-pipe",
                                     "--user-data-dir=" + profile_dir.string(),
                                     "--window-size=" + std::to_string(width) + "," + std::to_string(height),
                                     "about:blank"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid_t pid = -1;
    const int spawned = ::posix_spawn(&pid, exe.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    ::close(to_browser[0]);
    ::close(from_browser[1]);
    auto browser = std::unique_ptr<HeadlessChromium>(new HeadlessChromium(pid, to_browser[1], from_browser[0]));
    if (spawned != 0) {
      browser->pid_ = -1;
      return nullptr;
    }
    if (!browser->Call("Browser.getVersion", {}, false, std::chrono::seconds(60))) return nullptr;
    return browser;
  }

  ~HeadlessChromium() {
    if (pid_ > 0) {
      Call("Browser.close", {}, false, std::chrono::seconds(5));
      for (int i = 0; i < 50 && ::waitpid(pid_, nullptr, WNOHANG) == 0; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
      if (::waitpid(pid_, nullptr, WNOHANG) == 0) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, nullptr, 0);
      }
    }
    ::close(write_fd_);
    ::close(read_fd_);
  }

  // A new tab showing `url`, which later calls talk to.
  bool Open(const std::string& url) {
    auto target = Call("Target.createTarget", {{"url", url}}, false);
    if (!target) return false;
    auto attached = Call("Target.attachToTarget", {{"targetId", (*target)["targetId"]}, {"flatten", true}}, false);
    if (!attached) return false;
    session_ = (*attached)["sessionId"].get<std::string>();
    return true;
  }

  // The value of a JavaScript expression in the tab; nullopt when it threw.
  std::optional<nlohmann::json> Evaluate(const std::string& expression) {
    auto result = Call("Runtime.evaluate", {{"expression", expression}, {"returnByValue", true}}, true);
    if (!result || result->contains("exceptionDetails")) return std::nullopt;
    return (*result)["result"].value("value", nlohmann::json());
  }

  // The tab as PNG bytes.
  std::optional<std::string> ScreenshotPng() {
    auto result = Call("Page.captureScreenshot", {{"format", "png"}}, true);
    if (!result) return std::nullopt;
    return DecodeBase64((*result)["data"].get<std::string>());
  }

 private:
  HeadlessChromium(pid_t pid, int write_fd, int read_fd) : pid_(pid), write_fd_(write_fd), read_fd_(read_fd) {}

  // Sends one command and waits for its reply, skipping the events between.
  std::optional<nlohmann::json> Call(const std::string& method, const nlohmann::json& params, bool in_tab,
                                     std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
    nlohmann::json message = {{"id", ++last_id_}, {"method", method}, {"params", params}};
    if (in_tab) message["sessionId"] = session_;
    const std::string text = message.dump() + '\0';
    if (::write(write_fd_, text.data(), text.size()) != static_cast<ssize_t>(text.size())) return std::nullopt;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      for (size_t end; (end = buffer_.find('\0')) != std::string::npos;) {
        auto reply = nlohmann::json::parse(buffer_.substr(0, end), nullptr, false);
        buffer_.erase(0, end + 1);
        if (reply.is_object() && reply.value("id", -1) == last_id_) {
          if (reply.contains("error")) return std::nullopt;
          return reply["result"];
        }
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      pollfd p{read_fd_, POLLIN, 0};
      if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) <= 0) return std::nullopt;
      char chunk[65536];
      const ssize_t n = ::read(read_fd_, chunk, sizeof chunk);
      if (n <= 0) return std::nullopt;
      buffer_.append(chunk, static_cast<size_t>(n));
    }
  }

  pid_t pid_;
  int write_fd_;
  int read_fd_;
  int last_id_ = 0;
  std::string session_;
  std::string buffer_;
};

}  // namespace tagsfm::testing
