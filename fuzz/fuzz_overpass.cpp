// The Overpass response path end to end: a loopback HTTP server in this process answers the
// client's POST with the input, which goes through libcurl (status line, headers, chunked or
// gzip bodies), the client's classification (HTTP status, runtime-error remarks, size cap),
// OverpassMapSource (parseOsmXml, buildings only) and the ENU projection the buffer applies.
// An input starting with "HTTP/" is sent verbatim; anything else is sent as the body of a
// "200 OK" answer with a Content-Length.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>

#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_map_source.h"

namespace {

std::mutex g_mutex;
std::string g_response;

void sendAll(int fd, const std::string& bytes) {
  size_t sent = 0;
  while (sent < bytes.size()) {
    const ssize_t n = ::send(fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return;
    sent += static_cast<size_t>(n);
  }
}

/// Reads the request (headers and Content-Length bytes of body) so that the answer is not
/// written into a half-read connection.
void readRequest(int fd) {
  std::string request;
  char buf[4096];
  size_t body_needed = std::string::npos;
  size_t header_end = std::string::npos;
  while (true) {
    const ssize_t n = ::recv(fd, buf, sizeof(buf), 0);
    if (n <= 0) return;
    request.append(buf, static_cast<size_t>(n));
    if (header_end == std::string::npos) {
      header_end = request.find("\r\n\r\n");
      if (header_end == std::string::npos) continue;
      header_end += 4;
      const size_t cl = request.find("Content-Length:");
      body_needed =
          cl == std::string::npos ? 0 : std::strtoul(request.c_str() + cl + 15, nullptr, 10);
    }
    if (request.size() >= header_end + body_needed) return;
  }
}

int startServer() {
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  if (listener < 0) std::abort();
  int one = 1;
  ::setsockopt(listener, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  if (::bind(listener, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0) std::abort();
  if (::listen(listener, 16) != 0) std::abort();
  socklen_t len = sizeof(addr);
  ::getsockname(listener, reinterpret_cast<sockaddr*>(&addr), &len);
  std::thread([listener] {
    while (true) {
      const int fd = ::accept(listener, nullptr, nullptr);
      if (fd < 0) continue;
      readRequest(fd);
      std::string response;
      {
        std::lock_guard<std::mutex> lock(g_mutex);
        response = g_response;
      }
      sendAll(fd, response);
      ::shutdown(fd, SHUT_WR);
      ::close(fd);
    }
  }).detach();
  return ntohs(addr.sin_port);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const int port = startServer();
  static osm_graph_slam::OverpassMapSource source([] {
    osm_graph_slam::OverpassParams params;
    params.endpoint = "http://127.0.0.1:" + std::to_string(port) + "/api/interpreter";
    params.timeout_s = 5.0;
    params.connect_timeout_s = 2.0;
    params.max_retries = 0;
    params.max_response_bytes = 1u << 20;
    return params;
  }());
  const std::string input(reinterpret_cast<const char*>(data), size);
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    if (input.rfind("HTTP/", 0) == 0) {
      g_response = input;
    } else {
      g_response = "HTTP/1.1 200 OK\r\nContent-Type: application/osm3s+xml\r\nContent-Length: " +
                   std::to_string(input.size()) + "\r\n\r\n" + input;
    }
  }
  osm_graph_slam::MapFetchResult result = source.fetch({49.0112, 8.4229}, 120.0);
  if (result.ok) {
    const osm_graph_slam::EnuConverter enu(49.0112, 8.4229, 112.8);
    for (auto& building : result.buildings) enu.project(building);
  }
  return 0;
}
