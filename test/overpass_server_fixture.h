#pragma once
// Starts scripts/overpass_test_server.py as a child process on a free loopback port and stops
// exactly that child. Shared by the OSM buffer gtest and the osm_buffer rostest node.
#include <curl/curl.h>
#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

namespace osm_graph_slam::test {

class OverpassTestServer {
 public:
  OverpassTestServer(std::string script, std::string osm_file)
      : script_(std::move(script)), osm_file_(std::move(osm_file)) {
    dir_ = std::filesystem::temp_directory_path() /
           ("ogs_overpass_" + std::to_string(::getpid()) + "_" + std::to_string(counter()++));
    std::filesystem::create_directories(dir_);
  }
  ~OverpassTestServer() {
    stop();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

  /// Starts the server (port 0 = a free one; pass the old port to come back on it).
  bool start(int port = 0, int latency_ms = 0) {
    const std::string port_file = (dir_ / "port").string();
    std::filesystem::remove(port_file);
    pid_ = ::fork();
    if (pid_ == 0) {
      const std::string port_s = std::to_string(port), latency_s = std::to_string(latency_ms);
      std::freopen("/dev/null", "w", stdout);
      ::execl("/usr/bin/python3", "python3", script_.c_str(), "--osm", osm_file_.c_str(), "--port",
              port_s.c_str(), "--port-file", port_file.c_str(), "--latency-ms", latency_s.c_str(),
              static_cast<char*>(nullptr));
      ::_exit(127);
    }
    if (pid_ < 0) return false;
    for (int i = 0; i < 300; ++i) {  // up to 30 s on a loaded machine
      std::ifstream in(port_file);
      if (in >> port_) return true;
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return false;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    stop();
    return false;
  }

  void stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    int status = 0;
    for (int i = 0; i < 50 && ::waitpid(pid_, &status, WNOHANG) == 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (::waitpid(pid_, &status, WNOHANG) == 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status, 0);
    }
    pid_ = -1;
  }

  int port() const { return port_; }
  std::string url() const {
    return "http://127.0.0.1:" + std::to_string(port_) + "/api/interpreter";
  }

  /// GET /control?<query> or /stats; returns the body ("" on failure).
  std::string get(const std::string& path_and_query) const {
    std::string body;
    CURL* h = curl_easy_init();
    if (!h) return body;
    const std::string u = "http://127.0.0.1:" + std::to_string(port_) + path_and_query;
    curl_easy_setopt(h, CURLOPT_URL, u.c_str());
    curl_easy_setopt(h, CURLOPT_TIMEOUT, 10L);
    curl_easy_setopt(h, CURLOPT_NOSIGNAL, 1L);
    curl_easy_setopt(h, CURLOPT_WRITEFUNCTION, &append);
    curl_easy_setopt(h, CURLOPT_WRITEDATA, &body);
    if (curl_easy_perform(h) != CURLE_OK) body.clear();
    curl_easy_cleanup(h);
    return body;
  }
  bool setMode(const std::string& mode, int latency_ms = -1) const {
    std::string q = "/control?mode=" + mode;
    if (latency_ms >= 0) q += "&latency_ms=" + std::to_string(latency_ms);
    return get(q).find("\"mode\": \"" + mode + "\"") != std::string::npos;
  }

 private:
  static size_t append(char* d, size_t s, size_t n, void* u) {
    static_cast<std::string*>(u)->append(d, s * n);
    return s * n;
  }
  static int& counter() {
    static int c = 0;
    return c;
  }

  std::string script_, osm_file_;
  std::filesystem::path dir_;
  pid_t pid_ = -1;
  int port_ = 0;
};

}  // namespace osm_graph_slam::test
