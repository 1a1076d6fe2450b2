#pragma once
// The daemon's messages to systemd (a Type=notify unit with WatchdogSec, see
// scripts/tagsfm.service): READY=1 once the camera, the recording and the
// dashboard are open; WATCHDOG=1 at a third of the watchdog period while
// frames keep coming (a capture stalled for `stall_limit` stops the pings,
// and systemd restarts the daemon); a one-line STATUS= at most once a
// second; STOPPING=1 when the capture ends, after which the pings go on
// through the final adjustment. Without NOTIFY_SOCKET (not under systemd)
// it does nothing.
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

namespace tagsfm {

class SystemdNotifier {
 public:
  explicit SystemdNotifier(std::chrono::milliseconds stall_limit);
  ~SystemdNotifier();
  SystemdNotifier(const SystemdNotifier&) = delete;
  SystemdNotifier& operator=(const SystemdNotifier&) = delete;

  void Ready(const std::string& status);
  // A frame went through; `status` is shown if a second has passed since the last.
  void Progress(const std::string& status);
  void Stopping(const std::string& status);
  bool watchdog_enabled() const { return watchdog_period_.count() > 0; }

 private:
  void Ping();

  std::chrono::microseconds watchdog_period_{0};  // a third of WATCHDOG_USEC; 0: no watchdog
  std::chrono::milliseconds stall_limit_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool ready_ = false;
  bool stopping_ = false;
  bool done_ = false;
  std::chrono::steady_clock::time_point last_progress_, last_status_;
  std::thread pinger_;
};

}  // namespace tagsfm
