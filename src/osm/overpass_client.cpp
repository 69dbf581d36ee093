#include "osm_graph_slam/osm/overpass_client.h"

#include <curl/curl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

void initCurlOnce() {
  static std::once_flag flag;
  std::call_once(flag, [] { curl_global_init(CURL_GLOBAL_DEFAULT); });
}

struct Transfer {
  std::string* body;
  size_t max_bytes;
  bool too_large = false;
  const std::atomic<bool>* cancelled;
};

size_t writeBody(char* data, size_t size, size_t count, void* user) {
  auto* transfer = static_cast<Transfer*>(user);
  const size_t n = size * count;
  if (transfer->body->size() + n > transfer->max_bytes) {
    transfer->too_large = true;
    return 0;  // makes libcurl abort with CURLE_WRITE_ERROR
  }
  transfer->body->append(data, n);
  return n;
}

int onProgress(void* user, curl_off_t, curl_off_t, curl_off_t, curl_off_t) {
  return static_cast<Transfer*>(user)->cancelled->load() ? 1 : 0;
}

OverpassError classifyCurlError(CURLcode code) {
  switch (code) {
    case CURLE_COULDNT_CONNECT:
    case CURLE_COULDNT_RESOLVE_HOST:
    case CURLE_COULDNT_RESOLVE_PROXY:
    case CURLE_SSL_CONNECT_ERROR:
    case CURLE_PEER_FAILED_VERIFICATION:
      return OverpassError::kConnect;
    case CURLE_OPERATION_TIMEDOUT:
      return OverpassError::kTimeout;
    case CURLE_ABORTED_BY_CALLBACK:
      return OverpassError::kCancelled;
    case CURLE_RECV_ERROR:
    case CURLE_SEND_ERROR:
    case CURLE_GOT_NOTHING:
    case CURLE_PARTIAL_FILE:
    case CURLE_BAD_CONTENT_ENCODING:
    case CURLE_HTTP2:
    case CURLE_HTTP2_STREAM:
      return OverpassError::kTransfer;
    default:
      return OverpassError::kOther;
  }
}

/// Transient faults are retried; a bad query (HTTP 400), an oversized answer or a cancel are not.
bool isTransient(const OverpassResult& r) {
  switch (r.error_kind) {
    case OverpassError::kConnect:
    case OverpassError::kTimeout:
    case OverpassError::kTransfer:
    case OverpassError::kServerRuntime:
      return true;
    case OverpassError::kHttpStatus:
      return r.http_status == 429 || r.http_status >= 500;
    default:
      return false;
  }
}

/// Overpass reports query timeouts and memory exhaustion as HTTP 200 with a remark.
bool findRuntimeRemark(const std::string& body, std::string& remark) {
  const size_t begin = body.find("<remark>");
  if (begin == std::string::npos) return false;
  const size_t end = body.find("</remark>", begin);
  remark = body.substr(begin + 8,
                       end == std::string::npos ? 200 : std::min<size_t>(end - begin - 8, 200));
  return remark.find("error") != std::string::npos;
}

std::string trimmed(const std::string& s, size_t max_len) {
  std::string out = s.substr(0, max_len);
  std::replace(out.begin(), out.end(), '\n', ' ');
  return out;
}

}  // namespace

const char* toString(OverpassError error) {
  switch (error) {
    case OverpassError::kNone:
      return "none";
    case OverpassError::kConnect:
      return "connect";
    case OverpassError::kTimeout:
      return "timeout";
    case OverpassError::kTransfer:
      return "transfer";
    case OverpassError::kHttpStatus:
      return "http_status";
    case OverpassError::kTooLarge:
      return "too_large";
    case OverpassError::kServerRuntime:
      return "server_runtime_error";
    case OverpassError::kCancelled:
      return "cancelled";
    case OverpassError::kOther:
      return "other";
  }
  return "other";
}

OverpassClient::OverpassClient(OverpassParams params) : params_(std::move(params)) {
  initCurlOnce();
}

std::string OverpassClient::buildingsQuery(double lat, double lon, double radius_m,
                                           int server_timeout_s) {
  std::ostringstream q;
  q.precision(10);
  const auto around = [&] {
    std::ostringstream a;
    a.precision(10);
    a << "(around:" << radius_m << "," << lat << "," << lon << ")";
    return a.str();
  }();
  q << "[out:xml][timeout:" << server_timeout_s << "];\n"
    << "(\n"
    << "  way[\"building\"]" << around << ";\n"
    << "  relation[\"building\"][\"type\"=\"multipolygon\"]" << around << ";\n"
    << ");\n"
    << "out body;\n"
    << ">;\n"
    << "out skel qt;\n";
  return q.str();
}

OverpassResult OverpassClient::fetchBuildings(double lat, double lon, double radius_m) const {
  return post(buildingsQuery(lat, lon, radius_m, params_.server_timeout_s));
}

OverpassResult OverpassClient::post(const std::string& query) const {
  const auto start = Clock::now();
  OverpassResult result;
  double wait_s = params_.backoff_initial_s;
  for (int attempt_index = 0; attempt_index <= params_.max_retries; ++attempt_index) {
    double retry_after_s = 0.0;
    result = attempt(query, &retry_after_s);
    result.attempts = attempt_index + 1;
    if (result.ok || !isTransient(result) || attempt_index == params_.max_retries) break;
    const double pause = std::min(params_.backoff_max_s, std::max(wait_s, retry_after_s));
    if (!sleepUnlessCancelled(pause)) {
      result.error_kind = OverpassError::kCancelled;
      result.error = "cancelled while waiting to retry after: " + result.error;
      break;
    }
    wait_s *= params_.backoff_factor;
  }
  result.elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
  if (!result.ok && result.attempts > 1) {
    result.error += " (after " + std::to_string(result.attempts) + " attempts)";
  }
  return result;
}

OverpassResult OverpassClient::attempt(const std::string& query, double* retry_after_s) const {
  OverpassResult result;
  if (cancelled_) {
    result.error_kind = OverpassError::kCancelled;
    result.error = "request cancelled";
    return result;
  }
  std::unique_ptr<CURL, decltype(&curl_easy_cleanup)> curl(curl_easy_init(), &curl_easy_cleanup);
  if (!curl) {
    result.error_kind = OverpassError::kOther;
    result.error = "curl_easy_init failed";
    return result;
  }
  CURL* h = curl.get();
  char* escaped = curl_easy_escape(h, query.c_str(), static_cast<int>(query.size()));
  const std::string form = std::string("data=") + (escaped ? escaped : "");
  curl_free(escaped);

  Transfer transfer{&result.body, params_.max_response_bytes, false, &cancelled_};
  char error_buffer[CURL_ERROR_SIZE] = {0};
  curl_easy_setopt(h, CURLOPT_URL, params_.endpoint.c_str());
  curl_easy_setopt(h, CURLOPT_PROTOCOLS_STR, "http,https");
  curl_easy_setopt(h, CURLOPT_POSTFIELDS, form.c_str());
  curl_easy_setopt(h, CURLOPT_POSTFIELDSIZE_LARGE, static_cast<curl_off_t>(form.size()));
  curl_easy_setopt(h, CURLOPT_USERAGENT, params_.user_agent.c_str());
  curl_easy_setopt(h, CURLOPT_ACCEPT_ENCODING, "");  // every encoding libcurl decodes (gzip...)
  curl_easy_setopt(h, CURLOPT_NOSIGNAL, 1L);         // timeouts from worker threads
  curl_easy_setopt(h, CURLOPT_TIMEOUT_MS, static_cast<long>(params_.timeout_s * 1000.0));
  curl_easy_setopt(h, CURLOPT_CONNECTTIMEOUT_MS,
                   static_cast<long>(params_.connect_timeout_s * 1000.0));
  curl_easy_setopt(h, CURLOPT_FOLLOWLOCATION, 1L);
  curl_easy_setopt(h, CURLOPT_MAXREDIRS, 3L);
  curl_easy_setopt(h, CURLOPT_SSL_VERIFYPEER, params_.verify_tls ? 1L : 0L);
  curl_easy_setopt(h, CURLOPT_SSL_VERIFYHOST, params_.verify_tls ? 2L : 0L);
  curl_easy_setopt(h, CURLOPT_MAXFILESIZE_LARGE,
                   static_cast<curl_off_t>(params_.max_response_bytes));
  curl_easy_setopt(h, CURLOPT_WRITEFUNCTION, &writeBody);
  curl_easy_setopt(h, CURLOPT_WRITEDATA, &transfer);
  curl_easy_setopt(h, CURLOPT_XFERINFOFUNCTION, &onProgress);
  curl_easy_setopt(h, CURLOPT_XFERINFODATA, &transfer);
  curl_easy_setopt(h, CURLOPT_NOPROGRESS, 0L);
  curl_easy_setopt(h, CURLOPT_ERRORBUFFER, error_buffer);

  const CURLcode code = curl_easy_perform(h);
  curl_easy_getinfo(h, CURLINFO_RESPONSE_CODE, &result.http_status);
  curl_off_t retry_after = 0;
  if (curl_easy_getinfo(h, CURLINFO_RETRY_AFTER, &retry_after) == CURLE_OK && retry_after > 0) {
    *retry_after_s = static_cast<double>(retry_after);
  }

  const std::string where = " from " + params_.endpoint;
  if (transfer.too_large || code == CURLE_FILESIZE_EXCEEDED) {
    result.error_kind = OverpassError::kTooLarge;
    result.error = "Overpass answer larger than " + std::to_string(params_.max_response_bytes) +
                   " bytes" + where + "; aborted";
  } else if (code != CURLE_OK) {
    result.error_kind = classifyCurlError(code);
    result.error = std::string("Overpass request failed") + where + ": " +
                   (error_buffer[0] ? error_buffer : curl_easy_strerror(code)) + " [" +
                   toString(result.error_kind) + "]";
  } else if (result.http_status != 200) {
    result.error_kind = OverpassError::kHttpStatus;
    result.error = "Overpass answered HTTP " + std::to_string(result.http_status) + where +
                   (result.http_status == 429 ? " (rate limited)" : "") +
                   (result.http_status == 504 ? " (gateway timeout, server busy)" : "") + ": " +
                   trimmed(result.body, 120);
  } else {
    std::string remark;
    if (findRuntimeRemark(result.body, remark)) {
      result.error_kind = OverpassError::kServerRuntime;
      result.error = "Overpass runtime error" + where + ": " + trimmed(remark, 200);
    } else {
      result.ok = true;
    }
  }
  if (!result.ok) result.body.clear();
  return result;
}

bool OverpassClient::sleepUnlessCancelled(double seconds) const {
  const auto until = Clock::now() + std::chrono::duration<double>(seconds);
  while (Clock::now() < until) {
    if (cancelled_) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return !cancelled_;
}

}  // namespace osm_graph_slam
