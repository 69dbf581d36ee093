// osm_buffer: OSM buildings around the vehicle (Overpass or a local file) in the ENU map frame.
// Thin adapter over OsmBuffer: parameters, gps/fix -> ENU origin, slam/pose -> query, publishers.
#include <geometry_msgs/PoseStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/NavSatFix.h>
#include <pluginlib/class_list_macros.hpp>

#include "osm_graph_slam/ros/nodelet_logging.h"

#include <cmath>
#include <memory>
#include <mutex>
#include <optional>
#include <set>

#include "osm_graph_slam/osm/osm_buffer.h"
#include "osm_graph_slam/osm/params_io.h"
#include "osm_graph_slam/ros/nodelet_params.h"
#include "osm_graph_slam/ros/osm_conversions.h"
#include "osm_graph_slam/ros/ros_param_reader.h"
#include "osm_graph_slam/slam/graph_dump.h"

namespace osm_graph_slam {

class OsmBufferNodelet : public nodelet::Nodelet {
 public:
  ~OsmBufferNodelet() override {
    timer_.stop();
    std::lock_guard<std::mutex> lock(mutex_);
    buffer_.reset();  // cancels a fetch in flight and joins the worker
  }

 private:
  void onInit() override {
    nh_ = getNodeHandle();
    pnh_ = getPrivateNodeHandle();
    readParams();
    logger_ = std::make_shared<const Logger>(nodeletLogSink(getName()));
    if (!createSource()) return;

    buildings_pub_ = nh_.advertise<BuildingArray>("osm/buildings", 1, true);
    markers_pub_ = nh_.advertise<visualization_msgs::MarkerArray>("osm/markers", 1, true);
    origin_pub_ = nh_.advertise<sensor_msgs::NavSatFix>("osm/origin", 1, true);
    fix_sub_ = nh_.subscribe("gps/fix", 10, &OsmBufferNodelet::onFix, this);
    pose_sub_ = nh_.subscribe("slam/pose", 10, &OsmBufferNodelet::onPose, this);
    timer_ = nh_.createTimer(ros::Duration(update_period_), &OsmBufferNodelet::onTimer, this);

    if (origin_param_.size() >= 2) {
      sensor_msgs::NavSatFix fix;
      fix.header.stamp = ros::Time::now();
      fix.latitude = origin_param_[0];
      fix.longitude = origin_param_[1];
      fix.altitude = origin_param_.size() >= 3 ? origin_param_[2] : 0.0;
      NODELET_INFO("ENU origin from the ~origin parameter");
      setOrigin(fix);
    }
  }

  /// Resumed mapping (~resume_map, as graph_backend's): the saved map's origin is the map frame.
  void originFromSavedMap() {
    std::string dir;
    pnh_.param("resume_map", dir, dir);
    if (dir.empty()) return;
    GraphDump dump;
    std::string error;
    if (!readGraphDump(dir + "/graph", dump, &error) || !dump.origin) {
      NODELET_ERROR("osm_buffer: no origin from the saved map %s (%s); using ~origin or gps/fix",
                    dir.c_str(), error.empty() ? "it has none" : error.c_str());
      return;
    }
    origin_param_ = {dump.origin->x(), dump.origin->y(), dump.origin->z()};
  }

  void readParams() {
    pnh_.param("origin", origin_param_, origin_param_);  // a list: not a ParamReader type
    originFromSavedMap();
    const RosParamReader reader(pnh_);
    OsmBufferNodeletParams np;  // defaults: nodelet_params.h
    osm_graph_slam::readParams(reader, np);
    source_ = np.source;
    osm_file_ = np.osm_file;
    map_frame_ = np.map_frame;
    update_period_ = np.update_period;
    min_publish_distance_ = np.min_publish_distance;
    osm_graph_slam::readParams(reader, buffer_params_);
    osm_graph_slam::readParams(reader, overpass_);
  }

  bool createSource() {
    if (source_ == "overpass") {
      source_ptr_ = std::make_shared<OverpassMapSource>(overpass_);
    } else if (source_ == "file") {
      auto file = std::make_shared<FileMapSource>(osm_file_);
      if (!file->loadError().empty()) {
        NODELET_ERROR_STREAM("~osm_file: " << file->loadError()
                                           << (file->loaded() ? " (serving what was read)" : ""));
      }
      if (!file->loaded()) return false;
      source_ptr_ = file;
    } else {
      NODELET_ERROR_STREAM("~source must be 'overpass' or 'file', not '" << source_
                                                                         << "'; osm_buffer idle");
      return false;
    }
    NODELET_INFO_STREAM("OSM buildings from " << source_ptr_->describe());
    return true;
  }

  static bool validFix(const sensor_msgs::NavSatFix& fix) {
    return fix.status.status >= sensor_msgs::NavSatStatus::STATUS_FIX &&
           std::isfinite(fix.latitude) && std::isfinite(fix.longitude) &&
           std::abs(fix.latitude) <= 90.0 && std::abs(fix.longitude) <= 180.0;
  }

  void onFix(const sensor_msgs::NavSatFix::ConstPtr& fix) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (buffer_) return;  // the origin is set once
    }
    if (!validFix(*fix)) {
      NODELET_WARN_THROTTLE(10.0,
                            "ignoring gps/fix without a valid fix (status %d, lat %f, lon %f)",
                            fix->status.status, fix->latitude, fix->longitude);
      return;
    }
    setOrigin(*fix);
  }

  void setOrigin(const sensor_msgs::NavSatFix& fix) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (buffer_ || !source_ptr_) return;
    const double alt = std::isfinite(fix.altitude) ? fix.altitude : 0.0;
    const EnuConverter enu(fix.latitude, fix.longitude, alt);
    buffer_ = std::make_unique<OsmBuffer>(source_ptr_, enu, buffer_params_, logger_);
    sensor_msgs::NavSatFix origin = fix;
    origin.header.frame_id = map_frame_;
    origin.altitude = alt;
    origin_pub_.publish(origin);
    NODELET_INFO("ENU origin set to lat %.7f lon %.7f alt %.2f", fix.latitude, fix.longitude, alt);
    buffer_->query(position_.value_or(Eigen::Vector2d::Zero()));  // starts the first fill
  }

  void onPose(const geometry_msgs::PoseStamped::ConstPtr& pose) {
    std::lock_guard<std::mutex> lock(mutex_);
    position_ = Eigen::Vector2d(pose->pose.position.x, pose->pose.position.y);
    last_stamp_ = pose->header.stamp;
    publishLocked(false);
  }

  void onTimer(const ros::TimerEvent&) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!buffer_) {
      NODELET_WARN_THROTTLE(10.0,
                            "waiting for a valid gps/fix (or the ~origin parameter) to set the "
                            "ENU origin before fetching OSM buildings");
      return;
    }
    publishLocked(true);
  }

  /// Queries the buffer at the latest pose (the origin before the first pose) and publishes when
  /// the vehicle moved, the answer changed or a new buffer arrived. Never waits on the network.
  void publishLocked(bool from_timer) {
    if (!buffer_) return;
    const Eigen::Vector2d p = position_.value_or(Eigen::Vector2d::Zero());
    const OsmQueryResult q = buffer_->query(p);
    if (!q.buffer_valid) {
      if (from_timer) {
        const OsmBufferStats s = buffer_->stats();
        NODELET_WARN_THROTTLE(10.0, "waiting for the first OSM buffer%s%s",
                              s.last_error.empty() ? "" : "; last error: ", s.last_error.c_str());
      }
      return;
    }
    std::set<int64_t> ids;
    for (const Building& b : q.buildings) ids.insert(b.id);
    const bool moved = !last_published_ || (p - *last_published_).norm() >= min_publish_distance_;
    if (!moved && ids == last_ids_ && q.generation == last_generation_) return;
    std_msgs::Header header;
    header.frame_id = map_frame_;
    header.stamp = last_stamp_.isZero() ? ros::Time::now() : last_stamp_;
    buildings_pub_.publish(buildingArrayToMsg(q.buildings, header, p, buffer_params_.query_radius));
    if (markers_pub_.getNumSubscribers() > 0 || ids != last_ids_) {
      markers_pub_.publish(buildingMarkers(q.buildings, header));
    }
    last_published_ = p;
    last_ids_ = std::move(ids);
    last_generation_ = q.generation;
  }

  ros::NodeHandle nh_, pnh_;
  ros::Publisher buildings_pub_, markers_pub_, origin_pub_;
  ros::Subscriber fix_sub_, pose_sub_;
  ros::Timer timer_;

  std::string source_, osm_file_, map_frame_;  // from OsmBufferNodeletParams
  double update_period_ = 0.0, min_publish_distance_ = 0.0;
  std::vector<double> origin_param_;
  OsmBufferParams buffer_params_;
  OverpassParams overpass_;

  std::shared_ptr<const Logger> logger_;
  std::shared_ptr<OsmMapSource> source_ptr_;
  std::mutex mutex_;
  std::unique_ptr<OsmBuffer> buffer_;
  std::optional<Eigen::Vector2d> position_;
  ros::Time last_stamp_;
  std::optional<Eigen::Vector2d> last_published_;
  std::set<int64_t> last_ids_;
  uint64_t last_generation_ = 0;
};

}  // namespace osm_graph_slam

PLUGINLIB_EXPORT_CLASS(osm_graph_slam::OsmBufferNodelet, nodelet::Nodelet)
