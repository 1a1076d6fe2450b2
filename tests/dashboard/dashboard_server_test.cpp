#include "tagsfm/dashboard/dashboard_server.h"

#include <chrono>
#include <future>
#include <thread>

#include <gtest/gtest.h>
#include <httplib.h>

namespace tagsfm {
namespace {

TEST(DashboardServer, ServesThePageTheStatusAndEvents) {
  auto server = DashboardServer::Start("127.0.0.1:0");
  ASSERT_TRUE(server) << server.error().message;
  const int port = (*server)->port();
  ASSERT_GT(port, 0);
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(5, 0);

  auto page = client.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("EventSource('/events')"), std::string::npos);

  (*server)->Publish(R"({"frame":7})");
  auto status = client.Get("/status");
  ASSERT_TRUE(status);
  EXPECT_EQ(status->body, R"({"frame":7})");
  EXPECT_EQ(status->get_header_value("Content-Type"), "application/json");

  // The event stream delivers what is published after the client connects.
  auto received = std::async(std::launch::async, [port] {
    httplib::Client events("127.0.0.1", port);
    events.set_read_timeout(5, 0);
    std::string text;
    events.Get("/events", [&](const char* data, size_t length) {
      text.append(data, length);
      return text.find("\"frame\":9") == std::string::npos;  // stop reading once it came
    });
    return text;
  });
  // Publish until the stream has it (the client may connect after the first).
  for (int i = 0; i < 50 && received.wait_for(std::chrono::milliseconds(100)) != std::future_status::ready; ++i) {
    (*server)->Publish(R"({"frame":9})");
  }
  ASSERT_EQ(received.wait_for(std::chrono::seconds(5)), std::future_status::ready);
  EXPECT_NE(received.get().find("data: {\"frame\":9}\n\n"), std::string::npos);

  const auto start = std::chrono::steady_clock::now();
  (*server)->Stop();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));  // never hangs
}

TEST(DashboardServer, BadAddressesAreClearErrors) {
  auto a = DashboardServer::Start("localhost");
  ASSERT_FALSE(a);
  EXPECT_NE(a.error().message.find("HOST:PORT"), std::string::npos);
  auto b = DashboardServer::Start("127.0.0.1:http");
  ASSERT_FALSE(b);
  EXPECT_NE(b.error().message.find("port"), std::string::npos);
  auto first = DashboardServer::Start("127.0.0.1:0");
  ASSERT_TRUE(first);
  auto taken = DashboardServer::Start("127.0.0.1:" + std::to_string((*first)->port()));
  ASSERT_FALSE(taken);
  EXPECT_NE(taken.error().message.find("cannot bind"), std::string::npos);
}

}  // namespace
}  // namespace tagsfm
