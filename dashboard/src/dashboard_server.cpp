#include "tagsfm/dashboard/dashboard_server.h"

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include <httplib.h>

#include "dashboard_page.h"

namespace tagsfm {
namespace {

// Enough workers that 50 idle connections, a few slow ones and a client that
// never reads leave threads for the operator's page; the timeouts free a
// worker held by such a client within seconds. Publish() never waits on a
// client: it only swaps the status under a lock no socket call is made in.
constexpr size_t kWorkerThreads = 64;
constexpr time_t kReadTimeoutS = 3;
constexpr time_t kWriteTimeoutS = 2;
constexpr size_t kMaxRequestBodyBytes = 4096;  // the dashboard takes no uploads

// The page is the only document; it may talk to this server and nothing else.
void SetSafetyHeaders(httplib::Response& res) {
  res.set_header("Content-Security-Policy",
                 "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; connect-src 'self'");
  res.set_header("X-Content-Type-Options", "nosniff");
  res.set_header("Cache-Control", "no-store");
}

void Harden(httplib::Server& server) {
  server.new_task_queue = [] { return new httplib::ThreadPool(kWorkerThreads); };
  server.set_read_timeout(kReadTimeoutS, 0);
  server.set_write_timeout(kWriteTimeoutS, 0);
  server.set_payload_max_length(kMaxRequestBodyBytes);
  // Only the three GET paths exist: anything else (another file, "/../",
  // another method) gets httplib's 404, or 400 for what is not HTTP.
  server.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    SetSafetyHeaders(res);
    res.set_content(res.status == 404 ? "not found\n" : "bad request\n", "text/plain");
  });
}

}  // namespace

struct DashboardServer::State {
  httplib::Server server;
  std::thread thread;
  std::string host;
  int port = 0;

  std::mutex mutex;
  std::condition_variable changed;
  std::string status = "{}";
  std::uint64_t version = 0;
  bool stopping = false;
};

DashboardServer::DashboardServer(std::unique_ptr<State> state) : state_(std::move(state)) {}

Result<std::unique_ptr<DashboardServer>> DashboardServer::Start(const std::string& address) {
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos) return MakeError("dashboard address '" + address + "': expected HOST:PORT");
  auto state = std::make_unique<State>();
  state->host = address.substr(0, colon);
  const std::string port_text = address.substr(colon + 1);
  int port = -1;
  try {
    size_t used = 0;
    port = std::stoi(port_text, &used);
    if (used != port_text.size()) port = -1;
  } catch (const std::exception&) {
    port = -1;
  }
  if (port < 0 || port > 65535) return MakeError("dashboard address '" + address + "': port must be 0-65535");

  State* s = state.get();
  // httplib's default also sets SO_REUSEPORT, which lets a second daemon
  // bind the same port and silently take half the connections.
  s->server.set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, reinterpret_cast<const void*>(&yes), sizeof yes);
  });
  Harden(s->server);
  s->server.Get("/", [](const httplib::Request&, httplib::Response& res) {
    SetSafetyHeaders(res);
    res.set_content(kDashboardPage, "text/html; charset=utf-8");
  });
  s->server.Get("/status", [s](const httplib::Request&, httplib::Response& res) {
    SetSafetyHeaders(res);
    std::lock_guard<std::mutex> lock(s->mutex);
    res.set_content(s->status, "application/json");
  });
  s->server.Get("/events", [s](const httplib::Request&, httplib::Response& res) {
    SetSafetyHeaders(res);
    auto last_sent = std::make_shared<std::uint64_t>(0);
    res.set_chunked_content_provider("text/event-stream", [s, last_sent](size_t, httplib::DataSink& sink) {
      std::unique_lock<std::mutex> lock(s->mutex);
      // Wake at least once a second so a stopped server or a gone client
      // ends the stream promptly.
      s->changed.wait_for(lock, std::chrono::seconds(1), [&] { return s->stopping || s->version != *last_sent; });
      if (s->version == *last_sent) {
        if (!s->stopping) return sink.is_writable();
        sink.done();
        return false;
      }
      // The latest status only: a client slower than the frames skips some.
      // On stopping, the last one still goes out, so a page ends on the final state.
      const std::string event = "data: " + s->status + "\n\n";
      *last_sent = s->version;
      lock.unlock();
      return sink.write(event.data(), event.size());
    });
  });

  if (port == 0) {
    s->port = s->server.bind_to_any_port(s->host);
    if (s->port <= 0) return MakeError("dashboard address '" + address + "': cannot bind");
  } else {
    if (!s->server.bind_to_port(s->host, port)) {
      return MakeError("dashboard address '" + address + "': cannot bind (port in use, or no such address?)");
    }
    s->port = port;
  }
  s->thread = std::thread([s] { s->server.listen_after_bind(); });
  // httplib's stop() does nothing before the accept loop runs; wait for it,
  // so that a Stop() right after Start() cannot leave the thread running.
  for (int i = 0; i < 500 && !s->server.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  return std::unique_ptr<DashboardServer>(new DashboardServer(std::move(state)));
}

DashboardServer::~DashboardServer() { Stop(); }

void DashboardServer::Publish(std::string status_json) {
  {
    std::lock_guard<std::mutex> lock(state_->mutex);
    state_->status = std::move(status_json);
    ++state_->version;
  }
  state_->changed.notify_all();
}

void DashboardServer::Stop() {
  {
    std::lock_guard<std::mutex> lock(state_->mutex);
    if (state_->stopping && !state_->thread.joinable()) return;
    state_->stopping = true;
  }
  state_->changed.notify_all();
  state_->server.stop();
  if (state_->thread.joinable()) state_->thread.join();
}

int DashboardServer::port() const { return state_->port; }

std::string DashboardServer::url() const { return "http://" + state_->host + ":" + std::to_string(state_->port) + "/"; }

}  // namespace tagsfm
