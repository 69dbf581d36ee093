// Overpass client and OsmBuffer against scripts/overpass_test_server.py (a child process on a
// free loopback port) serving the real Karlsruhe extract of KITTI drive 0005.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <set>
#include <thread>

#include "osm_graph_slam/osm/osm_buffer.h"
#include "osm_graph_slam/osm/osm_reader.h"
#include "overpass_server_fixture.h"
#include "test_data.h"

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;
const std::string kOsm = "osm/2011_09_26_drive_0005_sync.osm";
constexpr double kLat0 = 49.0111, kLon0 = 8.4240;  // the dense centre of the extract

std::string serverScript() {
  return test::sourceDir() + "/scripts/overpass_test_server.py";
}

/// Captures every log line (thread-safe) so tests can assert what was said.
struct LogCapture {
  std::mutex mutex;
  std::vector<std::string> lines;
  std::shared_ptr<const Logger> logger() {
    return std::make_shared<const Logger>([this](LogLevel level, const std::string& m) {
      std::lock_guard<std::mutex> lock(mutex);
      lines.push_back((level == LogLevel::kWarn ? "WARN " : "INFO ") + m);
    });
  }
  size_t count(const std::string& needle) {
    std::lock_guard<std::mutex> lock(mutex);
    return std::count_if(lines.begin(), lines.end(),
                         [&](const std::string& l) { return l.find(needle) != std::string::npos; });
  }
  size_t size() {
    std::lock_guard<std::mutex> lock(mutex);
    return lines.size();
  }
  std::string dump() {
    std::lock_guard<std::mutex> lock(mutex);
    std::string all;
    for (const auto& l : lines) all += l + "\n";
    return all;
  }
};

OverpassParams fastParams(const std::string& url) {
  OverpassParams p;
  p.endpoint = url;
  p.timeout_s = 10.0;
  p.max_retries = 0;
  p.backoff_initial_s = 0.05;
  p.user_agent = "osm_graph_slam_test/1.0";
  return p;
}

OsmBufferParams fastRetryBuffer() {
  OsmBufferParams p;
  p.retry_initial_s = 0.05;
  p.retry_max_s = 0.2;
  return p;
}

/// Ground truth computed differently from the code under test: point-in-polygon by winding
/// angle, edge distance by dense sampling (5 cm). Returns a distance accurate to ~3 cm.
double referenceDistance(const Polygon2& outline, const Eigen::Vector2d& p) {
  double winding = 0.0;
  double best = 1e18;
  for (size_t i = 0; i < outline.size(); ++i) {
    const Eigen::Vector2d a = outline[i] - p, b = outline[(i + 1) % outline.size()] - p;
    winding += std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));
    const int steps = std::max(1, static_cast<int>((b - a).norm() / 0.05));
    for (int k = 0; k <= steps; ++k) best = std::min(best, (a + (b - a) * k / steps).norm());
  }
  return std::abs(winding) > M_PI ? 0.0 : best;
}

std::set<int64_t> ids(const std::vector<Building>& buildings) {
  std::set<int64_t> out;
  for (const Building& b : buildings) out.insert(b.id);
  return out;
}

class OsmBufferServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    osm_path_ = test::sharedDataPath(kOsm);
    if (!std::filesystem::exists(osm_path_)) {
      GTEST_SKIP() << "shared data file " << osm_path_ << " is absent; skipping";
    }
    server_ = std::make_unique<test::OverpassTestServer>(serverScript(), osm_path_);
    ASSERT_TRUE(server_->start()) << "could not start " << serverScript();
  }
  std::string osm_path_;
  std::unique_ptr<test::OverpassTestServer> server_;
  EnuConverter enu_{kLat0, kLon0};
};

TEST(OverpassClient, QueryAsksForBuildingWaysRelationsAndTheirNodes) {
  const std::string q = OverpassClient::buildingsQuery(49.5, 8.25, 120.0, 25);
  EXPECT_NE(q.find("[timeout:25]"), std::string::npos);
  EXPECT_NE(q.find("way[\"building\"](around:120,49.5,8.25)"), std::string::npos) << q;
  EXPECT_NE(q.find("relation[\"building\"][\"type\"=\"multipolygon\"](around:120,49.5,8.25)"),
            std::string::npos)
      << q;
  EXPECT_NE(q.find("out body;\n>;\nout skel qt;"), std::string::npos) << q;
}

TEST(OverpassClient, ConnectionRefusedIsAConnectError) {
  // A port nothing listens on: bind, read the port, close.
  OverpassParams p = fastParams("http://127.0.0.1:9/api/interpreter");
  p.max_retries = 2;
  const OverpassResult r = OverpassClient(p).fetchBuildings(kLat0, kLon0, 50);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error_kind, OverpassError::kConnect) << r.error;
  EXPECT_EQ(r.attempts, 3);
  EXPECT_NE(r.error.find("after 3 attempts"), std::string::npos) << r.error;
}

TEST_F(OsmBufferServerTest, ClientFetchesGzippedAnswerWithUserAgent) {
  OverpassClient client(fastParams(server_->url()));
  const OverpassResult r = client.fetchBuildings(kLat0, kLon0, 120.0);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.http_status, 200);
  EXPECT_EQ(r.attempts, 1);
  const OsmData data = parseOsmXml(r.body);
  ASSERT_TRUE(data.ok) << data.error;
  EXPECT_EQ(data.buildings.size(), 79u);  // curl + Python cross-check of this query
  const std::string stats = server_->get("/stats");
  EXPECT_NE(stats.find("\"user_agent\": \"osm_graph_slam_test/1.0\""), std::string::npos) << stats;
  EXPECT_NE(stats.find("gzip"), std::string::npos) << stats;  // Accept-Encoding sent
}

TEST_F(OsmBufferServerTest, OverpassAndFileSourcesAgreeOnTheBuildingSet) {
  OverpassMapSource overpass(fastParams(server_->url()));
  FileMapSource file(osm_path_);
  ASSERT_TRUE(file.loaded()) << file.loadError();
  EXPECT_EQ(file.size(), 170u);
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(0, 0), Eigen::Vector2d(-150, 80),
                                   Eigen::Vector2d(230, -120), Eigen::Vector2d(40, 300)}) {
    const GeoPoint g = enu_.toGeoPoint(p);
    for (double radius : {35.0, 120.0}) {
      const MapFetchResult a = overpass.fetch(g, radius);
      const MapFetchResult b = file.fetch(g, radius);
      ASSERT_TRUE(a.ok && b.ok) << a.error << b.error;
      EXPECT_EQ(ids(a.buildings), ids(b.buildings)) << "at " << p.transpose() << " r " << radius;
    }
  }
}

TEST_F(OsmBufferServerTest, ClientClassifiesEveryInjectedFault) {
  OverpassParams params = fastParams(server_->url());
  params.max_response_bytes = 1u << 20;
  params.max_retries = 1;
  OverpassClient client(params);
  struct Case {
    std::string mode;
    OverpassError kind;
    long status;
    int attempts;
  };
  const std::vector<Case> cases = {
      {"http429", OverpassError::kHttpStatus, 429, 2},
      {"http504", OverpassError::kHttpStatus, 504, 2},
      {"drop", OverpassError::kTransfer, 0, 2},
      {"short_read", OverpassError::kTransfer, 200, 2},
      {"oversize", OverpassError::kTooLarge, 200, 1},
      {"remark", OverpassError::kServerRuntime, 200, 2},
  };
  for (const Case& c : cases) {
    ASSERT_TRUE(server_->setMode(c.mode)) << c.mode;
    const OverpassResult r = client.fetchBuildings(kLat0, kLon0, 120.0);
    EXPECT_FALSE(r.ok) << c.mode;
    EXPECT_EQ(r.error_kind, c.kind) << c.mode << ": " << r.error;
    EXPECT_EQ(r.http_status, c.status) << c.mode << ": " << r.error;
    EXPECT_EQ(r.attempts, c.attempts) << c.mode;
    EXPECT_TRUE(r.body.empty());
    EXPECT_FALSE(r.error.empty());
  }
  // A slow server: the per-attempt timeout fires.
  ASSERT_TRUE(server_->setMode("normal", 3000));
  params.timeout_s = 0.5;
  params.max_retries = 0;
  const OverpassResult slow = OverpassClient(params).fetchBuildings(kLat0, kLon0, 120.0);
  EXPECT_EQ(slow.error_kind, OverpassError::kTimeout) << slow.error;
}

TEST_F(OsmBufferServerTest, QueriesReturnExactlyTheBuildingsWithinTheRadius) {
  const OsmData all = readOsmFile(osm_path_);
  ASSERT_TRUE(all.ok);
  std::vector<Building> truth = all.buildings;
  for (Building& b : truth) enu_.project(b);

  LogCapture log;
  OsmBuffer buffer(std::make_shared<OverpassMapSource>(fastParams(server_->url())), enu_,
                   fastRetryBuffer(), log.logger());
  ASSERT_TRUE(buffer.fillBlocking({0, 0}, 30.0)) << log.dump();
  size_t compared = 0, nonempty = 0;
  // A drive east then north, 2 m steps; refills happen on the way (waited for, so that the
  // comparison covers several buffers).
  for (int step = 0; step < 200; ++step) {
    const Eigen::Vector2d p = step < 100 ? Eigen::Vector2d(2.0 * step, 0.3 * step)
                                         : Eigen::Vector2d(200.0, 30.0 + 2.0 * (step - 100));
    const OsmQueryResult q = buffer.query(p);
    ASSERT_TRUE(q.buffer_valid);
    ASSERT_LE((p - q.buffer_centre).norm(), 120.0 - 35.0) << "query not covered by the buffer";
    std::set<int64_t> expected;
    std::set<int64_t> borderline;
    for (const Building& b : truth) {
      const double d = referenceDistance(b.outline_enu, p);
      if (d <= 35.0 - 0.05) expected.insert(b.id);
      if (std::abs(d - 35.0) < 0.05) borderline.insert(b.id);
    }
    std::set<int64_t> got = ids(q.buildings);
    for (int64_t id : borderline) got.erase(id);
    EXPECT_EQ(got, expected) << "at " << p.transpose();
    for (const Building& b : q.buildings) {
      EXPECT_EQ(b.segments.size(), b.outline_enu.size());  // projected in the map frame
    }
    ++compared;
    nonempty += expected.empty() ? 0 : 1;
    buffer.waitForIdle(30.0);
  }
  EXPECT_EQ(compared, 200u);
  EXPECT_GE(nonempty, 50u);  // 65 of the 200 keyframes see buildings on this drive
  EXPECT_GE(buffer.stats().fills_ok, 4u);
  EXPECT_EQ(buffer.stats().fills_failed, 0u) << log.dump();
}

TEST_F(OsmBufferServerTest, QueriesDoNotWaitForARefillAgainst2000MsLatency) {
  ASSERT_TRUE(server_->setMode("normal", 2000));
  LogCapture log;
  OsmBuffer buffer(std::make_shared<OverpassMapSource>(fastParams(server_->url())), enu_,
                   fastRetryBuffer(), log.logger());
  const auto t0 = Clock::now();
  ASSERT_TRUE(buffer.fillBlocking({0, 0}, 30.0)) << log.dump();
  const double first_fill_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  EXPECT_GE(first_fill_ms, 2000.0);  // the latency is real

  // Keyframes every 1 m at ~10 m/s: past 60 m the refill starts; the old buffer answers.
  double worst_ms = 0.0, worst_in_flight_ms = 0.0;
  size_t in_flight_queries = 0;
  for (int i = 0; i <= 100; ++i) {
    const Eigen::Vector2d p(static_cast<double>(i), 0.0);
    const auto q0 = Clock::now();
    const OsmQueryResult q = buffer.query(p);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - q0).count();
    worst_ms = std::max(worst_ms, ms);
    ASSERT_TRUE(q.buffer_valid);
    if (q.refill_in_flight) {
      ++in_flight_queries;
      worst_in_flight_ms = std::max(worst_in_flight_ms, ms);
      EXPECT_EQ(q.generation, 1u);  // still the old buffer
      EXPECT_FALSE(q.buildings.empty());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
  }
  std::cout << "[OSM buffer] first fill " << first_fill_ms << " ms; " << in_flight_queries
            << " queries while a refill was in flight, worst " << worst_in_flight_ms
            << " ms (worst overall " << worst_ms << " ms)\n";
  EXPECT_GE(in_flight_queries, 20u);  // 2 s of latency spans ~40 keyframes of 40 ms
  // Behavioural bound of the design (the 10 ms); generous against machine noise. A
  // query that waited for the refill would take the server's 2,000 ms: under AddressSanitizer
  // (several times slower) 50 ms still tells the two apart.
#if defined(__SANITIZE_ADDRESS__)
  EXPECT_LT(worst_in_flight_ms, 50.0);
#else
  EXPECT_LT(worst_in_flight_ms, 10.0);
#endif
  ASSERT_TRUE(buffer.waitForIdle(30.0));
  EXPECT_EQ(buffer.stats().generation, 2u);
  EXPECT_GT(buffer.stats().centre.x(), 60.0);
}

TEST_F(OsmBufferServerTest, ServerDownThenBackKeepsServingAndRecovers) {
  LogCapture log;
  OsmBuffer buffer(std::make_shared<OverpassMapSource>(fastParams(server_->url())), enu_,
                   fastRetryBuffer(), log.logger());
  ASSERT_TRUE(buffer.fillBlocking({0, 0}, 30.0));
  const std::set<int64_t> at_70 = ids(buffer.query({70, 0}).buildings);
  ASSERT_TRUE(buffer.waitForIdle(30.0));  // this query refilled around (70, 0)
  ASSERT_EQ(buffer.stats().generation, 2u);
  const int port = server_->port();
  server_->stop();

  // Keep driving: refills fail, the buffer around (70, 0) keeps answering.
  for (int i = 0; i < 30; ++i) {
    const OsmQueryResult q = buffer.query({140.0 + i, 0});
    EXPECT_EQ(q.generation, 2u);
    EXPECT_TRUE(q.buffer_valid);
    buffer.waitForIdle(30.0);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(ids(buffer.query({70, 0}).buildings), at_70);
  EXPECT_GE(buffer.stats().fills_failed, 2u);
  EXPECT_EQ(log.count("[connect]"), 1u) << log.dump();  // logged once, not per retry
  EXPECT_EQ(log.count("keeping the current buffer"), 1u) << log.dump();

  ASSERT_TRUE(server_->start(port)) << "could not restart on port " << port;
  bool recovered = false;
  for (int i = 0; i < 100 && !recovered; ++i) {
    buffer.query({170, 0});
    buffer.waitForIdle(30.0);
    recovered = buffer.stats().generation == 3u;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_TRUE(recovered) << log.dump();
  EXPECT_NEAR(buffer.stats().centre.x(), 170.0, 1.0);
  EXPECT_EQ(log.count("recovered after"), 1u) << log.dump();
  EXPECT_EQ(buffer.stats().consecutive_failures, 0u);
}

TEST_F(OsmBufferServerTest, EveryInjectedFaultIsLoggedAndLeavesTheBufferUnchanged) {
  OverpassParams params = fastParams(server_->url());
  params.max_response_bytes = 1u << 20;
  params.timeout_s = 1.0;
  LogCapture log;
  OsmBuffer buffer(std::make_shared<OverpassMapSource>(params), enu_, fastRetryBuffer(),
                   log.logger());
  ASSERT_TRUE(buffer.fillBlocking({0, 0}, 30.0));
  const std::set<int64_t> reference = ids(buffer.query({0, 0}).buildings);
  ASSERT_FALSE(reference.empty());

  struct Fault {
    std::string mode;
    int latency_ms;
    std::string logged;  // what the log line must say
  };
  const std::vector<Fault> faults = {
      {"http429", 0, "HTTP 429"},
      {"http504", 0, "HTTP 504"},
      {"drop", 0, "[transfer]"},
      {"short_read", 0, "[transfer]"},
      {"truncate", 0, "not valid OSM XML"},
      {"malformed", 0, "not valid OSM XML"},
      {"oversize", 0, "larger than"},
      {"remark", 0, "runtime error"},
      {"normal", 2500, "[timeout]"},
  };
  // Before every fault a successful refill at A (which also clears the log-once keys), then
  // the fault hits the refill at B: the buffer around A must stay exactly as it was.
  const Eigen::Vector2d a(0, 0), b(70, 0);
  for (const Fault& f : faults) {
    ASSERT_TRUE(server_->setMode("normal", 0));
    std::this_thread::sleep_for(std::chrono::milliseconds(250));      // > retry back-off
    buffer.query((buffer.stats().centre - a).norm() < 1e-6 ? b : a);  // refill somewhere else ...
    ASSERT_TRUE(buffer.waitForIdle(30.0));
    buffer.query(a);  // ... and back at A
    ASSERT_TRUE(buffer.waitForIdle(30.0));
    const OsmBufferStats before = buffer.stats();
    ASSERT_LT((before.centre - a).norm(), 1e-6) << log.dump();
    const std::set<int64_t> ids_before = ids(buffer.query(a).buildings);
    ASSERT_EQ(ids_before, reference);

    ASSERT_TRUE(server_->setMode(f.mode, f.latency_ms)) << f.mode;
    const size_t lines_before = log.count(f.logged);
    buffer.query(b);
    ASSERT_TRUE(buffer.waitForIdle(30.0));
    const OsmBufferStats after = buffer.stats();
    EXPECT_EQ(after.generation, before.generation) << f.mode << " changed the buffer";
    EXPECT_EQ(after.fills_failed, before.fills_failed + 1) << f.mode;
    EXPECT_LT((after.centre - a).norm(), 1e-6) << f.mode;
    EXPECT_EQ(ids(buffer.query(a).buildings), reference) << f.mode;
    EXPECT_EQ(log.count(f.logged), lines_before + 1) << f.mode << "\n" << log.dump();
    EXPECT_NE(after.last_error.find(f.logged), std::string::npos) << after.last_error;
  }
  EXPECT_EQ(log.count("keeping the current buffer"), faults.size()) << log.dump();
  EXPECT_EQ(log.count("recovered after 1 failed"), faults.size() - 1) << log.dump();
}

TEST(OsmBuffer, FileSourceServesTheBufferWithoutNetwork) {
  const std::string path = test::sharedDataPath(kOsm);
  OGS_REQUIRE_SHARED_FILE(path);
  auto source = std::make_shared<FileMapSource>(path);
  ASSERT_TRUE(source->loaded());
  LogCapture log;
  OsmBuffer buffer(source, EnuConverter(kLat0, kLon0), OsmBufferParams(), log.logger());
  EXPECT_FALSE(buffer.query({0, 0}).buffer_valid);  // first query starts the fill, no wait
  ASSERT_TRUE(buffer.waitForIdle(30.0));
  const OsmQueryResult q = buffer.query({0, 0});
  ASSERT_TRUE(q.buffer_valid);
  EXPECT_FALSE(q.buildings.empty());
  EXPECT_EQ(buffer.stats().buildings, 79u);  // the Overpass test server's 120 m answer
  for (const Building& b : q.buildings) {
    EXPECT_LE(outlineDistance(b.outline_enu, {0, 0}), 35.0);
    double lowest = 1e9;
    for (const auto& v : b.outline_enu) lowest = std::min(lowest, v.x());
    EXPECT_DOUBLE_EQ(b.reference_pose.x, lowest);
  }
}

TEST(OsmBuffer, UnreadableFileIsReportedOnceAndNeverFills) {
  auto source = std::make_shared<FileMapSource>("/nonexistent/city.osm.pbf");
  EXPECT_FALSE(source->loaded());
  LogCapture log;
  OsmBufferParams params = fastRetryBuffer();
  OsmBuffer buffer(source, EnuConverter(kLat0, kLon0), params, log.logger());
  for (int i = 0; i < 5; ++i) {
    EXPECT_FALSE(buffer.query({0, 0}).buffer_valid);
    buffer.waitForIdle(10.0);
    std::this_thread::sleep_for(std::chrono::milliseconds(60));
  }
  EXPECT_GE(buffer.stats().fills_failed, 2u);
  EXPECT_EQ(log.count("[file_unreadable]"), 1u) << log.dump();
  EXPECT_EQ(log.count("cannot open"), 1u) << log.dump();
}

TEST(OsmBuffer, OutlineDistance) {
  const Polygon2 square = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  EXPECT_DOUBLE_EQ(outlineDistance(square, {5, 5}), 0.0);
  EXPECT_DOUBLE_EQ(outlineDistance(square, {15, 5}), 5.0);
  EXPECT_DOUBLE_EQ(outlineDistance(square, {13, 14}), 5.0);
  EXPECT_DOUBLE_EQ(outlineDistance(square, {-2, 5}), 2.0);
}

}  // namespace
}  // namespace osm_graph_slam
