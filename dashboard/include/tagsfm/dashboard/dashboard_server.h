#pragma once
// GET /        the dashboard page
// GET /status  the latest status, JSON
// GET /events  the status as server-sent events, one per Publish()
#include <memory>
#include <string>

#include "tagsfm/core/result.h"

namespace tagsfm {

class DashboardServer {
 public:
  // Binds `address` ("HOST:PORT"; port 0 picks a free one) and serves from a
  // thread of its own until Stop() or destruction.
  static Result<std::unique_ptr<DashboardServer>> Start(const std::string& address);
  ~DashboardServer();
  DashboardServer(const DashboardServer&) = delete;
  DashboardServer& operator=(const DashboardServer&) = delete;

  void Publish(std::string status_json);
  void Stop();
  int port() const;
  std::string url() const;

 private:
  struct State;
  explicit DashboardServer(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace tagsfm
