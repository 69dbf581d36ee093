// Many drives, one map: merges the graph dumps of several drives (offline_slam --dump, with
// clouds) into one map (slam/session_merge.h, doc/fleet.md). Writes the merged map as save_map
// does, each session's trajectory, and a JSON summary. Exit status: 0 merged from every session,
// 3 merged but some sessions could not be read (listed in the summary), 1 nothing merged.
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "osm_graph_slam/common/logger.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/slam/graph_dump.h"
#include "osm_graph_slam/slam/map_export.h"
#include "osm_graph_slam/slam/pipeline_params_io.h"
#include "osm_graph_slam/slam/session_merge.h"
#include "support/command_line.h"
#include "support/pipeline_config.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::CommandLine;
namespace fs = std::filesystem;

namespace {

struct SessionFile {
  std::string dir;
  bool ok = false;
  std::string error;
  size_t keyframes_without_cloud = 0;
};

std::string jsonString(const std::string& s) {
  std::ostringstream out;
  out << '"';
  for (char c : s) {
    if (c == '"' || c == '\\')
      out << '\\' << c;
    else if (static_cast<unsigned char>(c) < 0x20)
      out << "\\u" << std::hex << std::setw(4) << std::setfill('0') << int(c) << std::dec;
    else
      out << c;
  }
  return out.str() + '"';
}

/// Reads one session's dump with its clouds; a dump without any cloud cannot take part in the
/// loop search but still brings its odometry, fixes and wall matches.
bool readSession(SessionFile& file, GraphDump& dump) {
  if (!readGraphDump(file.dir, dump, &file.error)) return false;
  std::string why;
  file.keyframes_without_cloud = loadDumpClouds(file.dir, dump, &why);
  if (file.keyframes_without_cloud > 0)
    std::cerr << "merge_sessions: " << file.dir << ": " << file.keyframes_without_cloud << " of "
              << dump.keyframes.size() << " keyframes have no cloud (" << why
              << "): they are not searched for inter-session loops\n";
  return true;
}

/// Each session's view of the merged map, a folder evaluate_map reads as a run: its keyframe
/// poses in the merged map (trajectory_tum.txt), the merged buildings, and dump/ linked to the
/// session's own dump (its clouds, with the session's own ids and stamps).
bool writeSessionRuns(const SessionMerge& merge, const std::vector<SessionFile>& files,
                      const std::vector<size_t>& merged_files, const std::string& out,
                      std::string* error) {
  std::vector<Trajectory> per_session(merged_files.size());
  for (const auto& kf : merge.backend().keyframes())
    if (kf.session < per_session.size()) per_session[kf.session].push_back({kf.stamp, kf.map_pose});
  for (size_t s = 0; s < merged_files.size(); ++s) {
    const fs::path dir = fs::path(out) / "sessions" / std::to_string(s);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (!writeTumTrajectory((dir / "trajectory_tum.txt").string(), per_session[s], error))
      return false;
    fs::remove(dir / "buildings_corrected.geojson", ec);
    fs::copy_file(fs::path(out) / "buildings_corrected.geojson",
                  dir / "buildings_corrected.geojson", ec);
    fs::remove(dir / "dump", ec);
    fs::create_directory_symlink(fs::absolute(files[merged_files[s]].dir), dir / "dump", ec);
    if (ec) {
      if (error) *error = "cannot write " + dir.string() + ": " + ec.message();
      return false;
    }
  }
  return true;
}

/// The inter-session loops by session and stamp (for the evaluation against ground truth).
bool writeInterSessionLoops(const SessionMerge& merge, const SessionMergeReport& report,
                            const std::string& path, std::string* error) {
  std::map<uint64_t, double> stamps;
  for (const auto& kf : merge.backend().keyframes()) stamps[kf.id] = kf.stamp;
  std::ostringstream csv;
  csv << std::setprecision(17)
      << "# from_session from_stamp to_session to_stamp x y z qx qy qz qw (from in to's frame)\n";
  for (const auto& l : report.inter_session_loops) {
    const Eigen::Quaterniond q(l.relative_pose.linear());
    const Eigen::Vector3d t = l.relative_pose.translation();
    csv << SessionMerge::sessionOf(l.from_id) << ' ' << stamps[l.from_id] << ' '
        << SessionMerge::sessionOf(l.to_id) << ' ' << stamps[l.to_id] << ' ' << t.x() << ' '
        << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w()
        << '\n';
  }
  return writeFileAtomically(path, csv.str(), error);
}

std::string summaryJson(const std::vector<SessionFile>& files, const SessionMergeReport& report,
                        double seconds) {
  std::ostringstream j;
  j << std::setprecision(6) << "{\n  \"sessions\": [";
  size_t merged = 0;
  for (size_t i = 0; i < files.size(); ++i) {
    const SessionFile& f = files[i];
    j << (i ? ",\n" : "\n") << "    {\"dir\": " << jsonString(f.dir)
      << ", \"ok\": " << (f.ok ? "true" : "false") << ", \"error\": " << jsonString(f.error);
    if (f.ok && merged < report.sessions.size()) {
      const SessionSummary& s = report.sessions[merged++];
      j << ", \"session\": " << s.session << ", \"keyframes\": " << s.keyframes
        << ", \"keyframes_without_cloud\": " << s.keyframes_without_cloud
        << ", \"inter_session_loops\": " << s.inter_session_loops;
    }
    j << "}";
  }
  j << "\n  ],\n  \"keyframes\": " << report.keyframes
    << ",\n  \"inter_session_loops\": " << report.inter_session_loops.size()
    << ",\n  \"loops_inconsistent\": " << report.loops_inconsistent
    << ",\n  \"loop_queries\": " << report.loop_queries << ",\n  \"buildings_by_drives\": {";
  bool first = true;
  for (const auto& [drives, count] : report.buildings_by_sessions) {
    j << (first ? "" : ", ") << "\"" << drives << "\": " << count;
    first = false;
  }
  j << "},\n  \"stage_seconds\": {\"add\": " << report.add_ms / 1e3
    << ", \"loops\": " << report.loops_ms / 1e3 << ", \"optimize\": " << report.optimize_ms / 1e3
    << ", \"uncertainty\": " << report.uncertainty_ms / 1e3 << "},\n";
  if (report.tiles)
    j << "  \"tiles\": {\"count\": " << report.tiles->tiles
      << ", \"sweeps\": " << report.tiles->sweeps
      << ", \"last_sweep_max_move_m\": " << report.tiles->last_sweep_max_move
      << ", \"largest_tile_keyframes\": " << report.tiles->largest_tile_keyframes
      << ", \"slowest_tile_seconds\": " << report.tiles->slowest_tile_ms / 1e3 << "},\n";
  j << "  \"merge_seconds\": " << seconds << "\n}\n";
  return j.str();
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> session_dirs;
  SessionMergeParams merge_params;
  CommandLine cli("merge_sessions",
                  "Merges the graph dumps of several drives (offline_slam --dump, with clouds) "
                  "into one map: one pose chain per drive, shared buildings, inter-session "
                  "loops. Exit 0: every session merged; 3: merged without the sessions that "
                  "could not be read; 1: nothing merged.");
  cli.option("--session", "DIR", "a drive's dump folder; repeatable, in the order to merge",
             [&session_dirs](const std::string& dir) {
               session_dirs.push_back(dir);
               return std::string();
             })
      .required()
      .option("--output", "DIR", "where the merged map (as save_map writes it) goes")
      .required()
      .option("--config", "OVERRIDES.yaml", "parameter overrides (as offline_slam --config)")
      .defaultText("config/kitti.yaml")
      .option("--json", "FILE", "the summary as JSON (default: OUTPUT/summary.json)")
      .option("--session-gap", "M",
              "inter-session loop search: the path gap the drives' relative uncertainty "
              "stands for",
              &merge_params.loop_search.session_gap)
      .flag("--no-inter-session-loops", "join the drives by their buildings only",
            &merge_params.inter_session_loops, false)
      .option("--tile-size", "M",
              "solve the merged graph in square map tiles of this size, tile by tile with the "
              "rest held, until they agree (0: one joint solve)",
              &merge_params.tiles.tile_size)
      .option("--tile-sweeps", "N", "at most N sweeps over the tiles",
              &merge_params.tiles.max_sweeps)
      .flag("--no-building-uncertainty",
            "skip the buildings' marginal deviations (tags of the corrected buildings)",
            &merge_params.building_uncertainty, false);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  std::map<std::string, std::string> args = cli.values();
  const auto t0 = std::chrono::steady_clock::now();

  SlamPipelineParams params;
  std::string error;
  if (!tools::loadToolConfig(args, params, &error)) {
    std::cerr << "merge_sessions: " << error << "\n";
    return 1;
  }
  merge_params.optimize_every = params.optimize_every_keyframes;
  const auto logger = std::make_shared<Logger>([](LogLevel level, const std::string& msg) {
    if (level >= LogLevel::kInfo) std::cerr << msg << "\n";
  });
  SessionMerge merge(params.backend, params.loop, merge_params, logger);
  std::vector<SessionFile> files;
  std::vector<size_t> merged_files;  ///< index in files of each merged session
  for (const auto& dir : session_dirs) {
    SessionFile file;
    file.dir = dir;
    GraphDump dump;
    file.ok = readSession(file, dump) && merge.addSession(dir, std::move(dump), &file.error);
    if (!file.ok)
      std::cerr << "merge_sessions: session " << dir << " left out: " << file.error << "\n";
    if (file.ok) merged_files.push_back(files.size());
    files.push_back(file);
  }
  if (merged_files.empty()) {
    std::cerr << "merge_sessions: no session could be read; nothing merged\n";
    return 1;
  }
  const SessionMergeReport report = merge.merge();
  const std::string out = args["output"];
  const MapExportResult saved = saveMap(merge.backend(), out, 0.2, &params.loop.scan_context);
  if (!saved.success) {
    std::cerr << "merge_sessions: the map was not saved: " << saved.message << "\n";
    return 1;
  }
  if (!writeSessionRuns(merge, files, merged_files, out, &error) ||
      !writeInterSessionLoops(merge, report, out + "/inter_session_loops.csv", &error)) {
    std::cerr << "merge_sessions: " << error << "\n";
    return 1;
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::string json_path = args.count("json") ? args["json"] : out + "/summary.json";
  if (!writeFileAtomically(json_path, summaryJson(files, report, seconds), &error)) {
    std::cerr << "merge_sessions: " << error << "\n";
    return 1;
  }
  std::cout << "merged " << merged_files.size() << " of " << files.size()
            << " sessions: " << report.keyframes << " keyframes, "
            << report.inter_session_loops.size() << " inter-session loops, "
            << merge.backend().buildings().size() << " buildings in " << seconds << " s -> " << out
            << "\n";
  return merged_files.size() == files.size() ? 0 : 3;
}
