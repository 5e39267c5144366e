// SPDX-License-Identifier: BSD-3-Clause
// Pictures of the evaluation report, drawn with OpenCV (DESIGN §5, issue #5): bird's-eye views of
// labelled scans, a clean-map overview, the ROC plot.
#pragma once
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "cleanmap/core/types.h"

namespace cleanmap::eval {

/// Outcome colours of a point in a bird's-eye view.
enum class Outcome { kTruePositive, kFalsePositive, kFalseNegative, kTrueNegative, kNotScored };
Outcome outcome(uint32_t predicted, uint32_t truth);

/// Bird's-eye view of one scan in its sensor frame, +-half_extent metres, 0.1 m per pixel:
/// TP red, FP orange, FN blue, static grey, not scored dark; with a legend and `title`.
cv::Mat birdsEyeView(const std::vector<PointXYZI>& points, const Labels& predicted,
                     const Labels& truth, double half_extent, const std::string& title);

/// Top view of a clean map (grey, brighter = more points) with `leftovers` (e.g. ground-truth
/// moving points the map still holds) in red. At most max_side pixels on the longer side.
cv::Mat mapOverview(const std::vector<Eigen::Vector3f>& map,
                    const std::vector<Eigen::Vector3f>& leftovers, const std::string& title,
                    int max_side = 1600);

struct RocCurvePoint {
  double fpr = 0, tpr = 0;
};
struct RocCurve {
  std::string label;
  std::vector<RocCurvePoint> points;
};
/// TPR vs FPR, one polyline per curve, `marked` drawn as a black ring (the default setting).
cv::Mat rocPlot(const std::vector<RocCurve>& curves, const RocCurvePoint& marked,
                const std::string& title);

/// Writes a PNG atomically; throws cleanmap::Error naming the file.
void writePng(const std::string& path, const cv::Mat& image);

}  // namespace cleanmap::eval
