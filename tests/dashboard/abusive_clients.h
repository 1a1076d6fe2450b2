#pragma once
// Clients that misbehave on purpose, for the dashboard abuse tests: 50 that
// connect and say nothing, 5 slow ones (two send their request a byte at a
// time, three read the event stream a few bytes at a time), one that asks
// for the event stream and never reads it, and a stream of malformed
// requests. They keep at it until `stop`.
#include <atomic>
#include <cerrno>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "raw_http.h"

namespace tagsfm::testing {

class Abusers {
 public:
  Abusers(int port, std::atomic<bool>& stop) {
    for (int i = 0; i < 50; ++i) idle_.push_back(ConnectLocal(port));  // connect, say nothing
    // One that asks for the event stream and never reads a byte of it.
    never_reads_ = ConnectLocal(port, 2048);
    SendAll(never_reads_, "GET /events HTTP/1.1\r\nHost: x\r\n\r\n");
    // Five slow ones: two send their request a byte at a time, three read
    // the event stream a few bytes at a time.
    for (int i = 0; i < 5; ++i) {
      threads_.emplace_back([port, i, &stop] {
        const int fd = ConnectLocal(port, 2048);
        if (i < 2) {
          for (char c : std::string("GET /status HTTP/1.1\r\nHost: x\r\n\r\n")) {
            if (stop || !SendAll(fd, std::string(1, c))) break;
            std::this_thread::sleep_for(std::chrono::milliseconds(150));
          }
        } else {
          SendAll(fd, "GET /events HTTP/1.1\r\nHost: x\r\n\r\n");
          SetReceiveTimeout(fd, 500);
          char few[16];
          while (!stop) {
            const ssize_t n = ::recv(fd, few, sizeof few, 0);
            if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) break;
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
          }
        }
        ::close(fd);
      });
    }
    // Malformed requests, over and over.
    threads_.emplace_back([port, &stop] {
      const std::string junk[] = {"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03 not http\r\n\r\n",
                                  "GET /status HTTP/9.9\r\n\r\n", "GET\r\n\r\n",
                                  "GET /status HTTP/1.1\r\nX: " + std::string(100000, 'a') + "\r\n\r\n",
                                  "POST / HTTP/1.1\r\nContent-Length: 1000000000\r\n\r\nabc",
                                  "GET /events HTTP/1.1\r\nRange: bytes=-\r\nHost\r\n\r\n"};
      while (!stop) {
        for (const auto& request : junk) RawExchange(port, request, std::chrono::milliseconds(500));
      }
    });
  }
  ~Abusers() {
    for (auto& t : threads_) t.join();
    for (int fd : idle_) ::close(fd);
    ::close(never_reads_);
  }

 private:
  std::vector<int> idle_;
  int never_reads_ = -1;
  std::vector<std::thread> threads_;
};

}  // namespace tagsfm::testing
