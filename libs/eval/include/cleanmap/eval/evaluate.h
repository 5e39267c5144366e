// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §5: scores a result (a cleanmap output folder, or any tool's clean map and/or per-scan
// labels) against a labelled sequence: per-point MOS (paper Table I), object level (Table II),
// DynamicMap SA/DA/AA/HA, and the run's time per stage.
#pragma once
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "cleanmap/core/map_score.h"
#include "cleanmap/core/metrics.h"

namespace cleanmap::eval {

/// What is being scored. Any part may be absent; at least one of labels and map is needed.
struct ResultInput {
  std::optional<std::string> labels_dir;  ///< <stem>.label per scan (SemanticKITTI-MOS ids)
  std::optional<std::string> map_path;    ///< clean map, world frame, .ply or .pcd
  std::optional<std::string> run_report;  ///< cleanmap report.json (runtime)
  std::optional<double> crop_tau;         ///< from the run's params.ini, when known

  /// RESULT is a cleanmap output folder (labels/, static_map_full.ply, report.json, params.ini)
  /// or a map file. `labels_dir` overrides / adds the labels. Throws cleanmap::Error naming RESULT.
  static ResultInput fromPath(const std::string& result,
                              const std::optional<std::string>& labels_dir);
};

struct EvalOptions {
  long first = 0, last = -1;  ///< scan range (indices in the ground truth, inclusive)
  /// Ground truth of the map scores: the labelled points within `map_range` metres horizontally
  /// of their scan's sensor (DESIGN §5, the DynamicMap convention: 50 m whatever the run's crop,
  /// so a map that covers less scores less); 0 = no limit.
  double map_range = 50.0;
  /// Also the per-axis crop |x|,|y|,|z| <= crop_tau (sensor frame), when set.
  std::optional<double> crop_tau;
  /// Use the run's own crop (params.ini `filter.crop_tau`) as crop_tau.
  bool run_crop = false;
  double radius = 0.05;      ///< m; DynamicMap "kept" distance
  std::string pictures_dir;  ///< when set: one bird's-eye PNG per scan + map overview
  /// Score the per-point and object measures only over the points that project into the
  /// sequence's camera image (in front of it, inside the image: KITTI image_2 with calib.txt P2
  /// and Tr), as the paper's Table I does with its image masks (DESIGN §5). The map scores are
  /// not restricted.
  bool camera_fov = false;
};

struct ObjectResult {
  int id = 0;
  std::string name, cls;
  uint64_t moving_points = 0;    ///< ground-truth moving points of the object inside the crop
  uint64_t labelled_moving = 0;  ///< of those, labelled moving by the result
  double fraction() const {
    return moving_points ? double(labelled_moving) / double(moving_points) : 0.0;
  }
  ObjectGrade grade() const { return gradeObject(fraction()); }
  bool scored() const { return moving_points > 0; }  ///< false: never inside the crop
};

/// "detected", "partial", "missed".
const char* gradeName(ObjectGrade g);

struct GradeCounts {
  int detected = 0, partial = 0, missed = 0;
};

struct StageTime {
  std::string stage;
  double median_ms = 0, p95_ms = 0;
};

struct RunTime {
  std::vector<StageTime> stages;  ///< "total" first
  int threads = 0;
  double peak_rss_mib = 0, wall_s = 0;
  std::size_t scans = 0;
};

struct EvalReport {
  std::string sequence, gt_dir, result;
  std::size_t scans = 0;
  double map_range = 0;  ///< m; 0 = no limit
  double crop_tau = 0;   ///< m; 0 = no per-axis crop
  double radius = 0;
  bool camera_fov = false;  ///< per-point and object measures inside the camera's view only
  std::optional<MosCounts> mos;
  std::vector<std::pair<std::string, MosCounts>> per_scan;
  std::optional<std::vector<ObjectResult>> objects;  ///< when objects.json and labels exist
  std::optional<MapScore> map;
  std::optional<RunTime> runtime;
  std::vector<std::string> pictures;  ///< file names written into pictures_dir

  /// Paper Table II counts over the scored objects (zeros without objects).
  GradeCounts gradeCounts() const;
};

/// DESIGN §5: is a labelled point (sensor frame) part of the map's ground truth? Within
/// `map_range` metres horizontally (0 = any) and, when crop_tau > 0, inside the per-axis crop.
bool inMapGroundTruth(const Eigen::Vector3f& p, double map_range, double crop_tau);

/// Throws cleanmap::Error (one line, naming the file) on missing or inconsistent inputs.
EvalReport evaluate(const std::string& gt_dir, const ResultInput& result, const EvalOptions& opt);

/// One JSON object: precision, recall, iou (with labels), SA, DA, AA, HA (with a map), counts,
/// objects, runtime.
std::string toJson(const EvalReport& r);
/// report.md + report.json into `dir` (atomically); pictures are referenced when present.
void writeReport(const std::string& dir, const EvalReport& r);

/// Markdown table, one row per report JSON (as toJson writes) and an overall row that sums the
/// counts. Throws cleanmap::Error naming a file that is not such a report.
std::string summaryTable(const std::vector<std::string>& json_files);

}  // namespace cleanmap::eval
