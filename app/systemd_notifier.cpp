#include "systemd_notifier.h"

#ifdef TAGSFM_HAVE_SYSTEMD
#include <systemd/sd-daemon.h>
#endif

namespace tagsfm {
namespace {

using Clock = std::chrono::steady_clock;

void Notify(const std::string& message) {
#ifdef TAGSFM_HAVE_SYSTEMD
  sd_notify(0, message.c_str());
#else
  (void)message;
#endif
}

// STATUS= takes one line.
std::string OneLine(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

}  // namespace

SystemdNotifier::SystemdNotifier(std::chrono::milliseconds stall_limit)
    : stall_limit_(stall_limit), last_progress_(Clock::now()), last_status_(Clock::now() - std::chrono::hours(1)) {
#ifdef TAGSFM_HAVE_SYSTEMD
  uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) watchdog_period_ = std::chrono::microseconds(usec / 3);
#endif
  if (watchdog_enabled()) pinger_ = std::thread([this] { Ping(); });
}

SystemdNotifier::~SystemdNotifier() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    done_ = true;
  }
  wake_.notify_all();
  if (pinger_.joinable()) pinger_.join();
}

// READY=1 goes out before the pinger may send its first WATCHDOG=1.
void SystemdNotifier::Ready(const std::string& status) {
  Notify("READY=1\nSTATUS=" + OneLine(status));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    last_progress_ = last_status_ = Clock::now();
    ready_ = true;
  }
  wake_.notify_all();
}

void SystemdNotifier::Progress(const std::string& status) {
  const auto now = Clock::now();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    last_progress_ = now;
    if (now - last_status_ < std::chrono::seconds(1)) return;
    last_status_ = now;
  }
  Notify("STATUS=" + OneLine(status));
}

void SystemdNotifier::Stopping(const std::string& status) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  Notify("STOPPING=1\nSTATUS=" + OneLine(status));
}

// Pings from READY=1 on while the capture makes progress, and always once it
// is stopping (the final adjustment may take longer than the watchdog period).
void SystemdNotifier::Ping() {
  std::unique_lock<std::mutex> lock(mutex_);
  wake_.wait(lock, [this] { return ready_ || stopping_ || done_; });
  while (!done_) {
    if (stopping_ || Clock::now() - last_progress_ < stall_limit_) {
      lock.unlock();
      Notify("WATCHDOG=1");
      lock.lock();
    }
    wake_.wait_for(lock, watchdog_period_, [this] { return done_; });
  }
}

}  // namespace tagsfm
