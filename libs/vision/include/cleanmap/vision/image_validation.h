// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §3 (paper §III, SPEC §3): a moving candidate that looks the same in every camera of its
// window is a false positive. OpenCV and Eigen only, beside the laser stages; no MRPT.
#pragma once
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "cleanmap/core/params.h"
#include "cleanmap/core/types.h"

namespace cleanmap::vision {

/// The nearest lidar return per pixel of one camera, row by row: the returns cover a few
/// per cent of the pixels, so a window's views hold 0.2 MB each instead of a full float image
/// (issue #16, doc/BENCHMARK.md, nineteenth session).
struct SparseDepth {
  int rows = 0, cols = 0;
  std::vector<int32_t> start;  ///< rows + 1: row y's returns are [start[y], start[y + 1])
  std::vector<uint16_t> col;   ///< increasing within a row
  std::vector<float> dist;     ///< camera-to-point distance (m)

  /// The pixels of `r` (which may reach outside the image) as CV_32F, +inf where no return.
  cv::Mat dense(const cv::Rect& r) const;
  /// The smallest distance in rows [y0, y1] and columns [x0, x1] (inclusive; +inf if none).
  float minIn(int y0, int y1, int x0, int x1) const;
};

/// One scan's camera, prepared once when the scan arrives and reused by every scan whose window
/// holds it: the image, the sparse lidar depth map and where the camera was.
struct CameraView {
  cv::Mat image;  ///< CV_8UC3, BGR
  /// The nearest lidar return per pixel (shared by corrected copies). The depth test's map,
  /// gaps closed by a disk dilation of `radius` px, is made from it patch by patch (depthPatch).
  std::shared_ptr<const SparseDepth> returns;
  int radius = 0;
  /// CV_32F, the same as a full image (+inf where no return): read by the photometric alignment,
  /// which looks up every sampled point at every iteration; released once the scan is aligned
  /// (release). Empty: `returns` is read, with the same values.
  cv::Mat sparse;
  /// CV_32F grey levels in [0, 1] of the image pyramid (cv::pyrDown), levels 1-3 at [1..3] ([0]
  /// empty): what the photometric alignment reads (alignment.h); released once the next scan is
  /// aligned on it.
  std::vector<cv::Mat> grey;
  Eigen::Isometry3d optical_from_world = Eigen::Isometry3d::Identity();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< camera centre, world frame
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::size_t index = 0;  ///< the scan's index

  bool empty() const { return image.empty(); }
};

/// Builds the view of scan `index`: `points` in the lidar frame, `pose` the lidar's pose in the
/// world, `radius` the depth map's dilation (px). Throws cleanmap::Error (naming `source`) if the
/// image is not the camera's size.
CameraView makeCameraView(const cv::Mat& bgr, const std::vector<PointXYZI>& points,
                          const Eigen::Isometry3d& pose, const PinholeCamera& cam,
                          std::size_t index, const std::string& source, int radius);

/// A world point seen by a camera: pixel and distance from the camera centre.
struct Projection {
  Eigen::Vector2d px = Eigen::Vector2d::Zero();
  double distance = 0;
};
/// Nullopt when the point is behind the camera or outside the image.
std::optional<Projection> project(const CameraView& v, const Eigen::Vector3d& world);

/// The depth test's map over `r` (inside the image): the nearest return within the view's
/// dilation disk of each pixel, +inf where none (SPEC §3; the same as dilating the whole map).
cv::Mat depthPatch(const CameraView& v, const cv::Rect& r);

/// The nearest lidar return at the pixel or its 8 neighbours (+inf if none): a point farther than
/// it by image.occlusion is hidden from the camera. The undilated map, so a foreground edge does
/// not hide what lies a few pixels beside it.
float nearestReturn(const CameraView& v, const Eigen::Vector2d& px);

/// True iff the intensity (mean of the channels, in [0, 1]) of a CV_32FC3 patch varies by more
/// than `min_std` and no channel is flat (NCC divides by each channel's deviation), over the
/// pixels of `mask` (CV_8U; empty = all).
bool isTextured(const cv::Mat& patch, double min_std, const cv::Mat& mask = cv::Mat());
/// Colour test: the largest over channels of E_c = 1 - max over shifts of the NCC of `tmpl`
/// (CV_32FC3) slid over `region` (CV_32FC3, at least as large), over the template pixels of
/// `mask` (CV_8U, the template's size; empty = all). With `stop_at`, the channels stop once one
/// reaches it (the verdict of a threshold of that value is the same).
double colourError(const cv::Mat& tmpl, const cv::Mat& region, const cv::Mat& mask = cv::Mat(),
                   double stop_at = std::numeric_limits<double>::infinity());
/// Depth test: the smallest over shifts of the mean squared difference between the template's
/// depths and the region's, each relative to its own expected depth of the point (`d_t`, `d_r`)
/// and divided by `d_t`. Pixels without a return in either are left out; nullopt when fewer than
/// half of the template's pixels can be compared at every shift. With `stop_below`, the first
/// shift whose error is below it ends the search (the verdict of a threshold of that value is the
/// same, the error returned is then not the smallest).
std::optional<double> depthError(const cv::Mat& tmpl, double d_t, const cv::Mat& region, double d_r,
                                 double stop_below = -std::numeric_limits<double>::infinity());

/// The unit normal (world frame, either sign) of the surface through `points` (world frame):
/// the axis of least spread, where they spread over a plane (at least 6 points, second spread
/// above (5 cm)^2, least spread below a tenth of it); nullopt otherwise (a line, a blob).
std::optional<Eigen::Vector3d> surfaceNormal(const std::vector<Eigen::Vector3d>& points);

/// True iff the surface of normal `normal` (world frame; zero: unknown, never) at `world` is
/// seen farther than max_incidence_deg from its normal by the camera at `centre`.
bool grazing(const Eigen::Vector3d& centre, const Eigen::Vector3d& world,
             const Eigen::Vector3d& normal, double max_incidence_deg);

/// What one camera of the window says about a point.
enum class Verdict : uint8_t {
  kUnseen,         ///< behind, outside the image, occluded, or no depth to compare
  kSimilarColour,  ///< the colour test matched: same appearance
  kSimilarDepth,   ///< uniform patch, the depth test matched
  kDifferentColour,
  kDifferentDepth,
  kGrazing,  ///< seen beyond image.max_incidence_deg from its surface's normal: not compared
};
/// Compares the point's patch in its own scan's view `ref` with its patch in `other`; `normal`
/// (world frame, zero: unknown) is its surface's: a camera that sees it grazing (either camera,
/// beyond p.max_incidence_deg) does not compare.
Verdict compareViews(const CameraView& ref, const CameraView& other, const Eigen::Vector3d& world,
                     const ImageParams& p, const Eigen::Vector3d& normal = Eigen::Vector3d::Zero());

/// The decision for one point (DESIGN §3): moving stays moving unless every window camera that
/// sees it finds it similar (and at least `min_views` do).
struct Decision {
  bool relabel_static = false;
  bool confirmed = false;  ///< some window camera found it different: it stays moving
  bool seen = false;       ///< the reference camera sees it and at least one window camera
  Verdict decisive = Verdict::kUnseen;  ///< the verdict that settled it (first different, or last
                                        ///< similar)
  bool used_depth = false;              ///< some window camera needed the depth test
  int views = 0;                        ///< window cameras compared
  int grazing = 0;                      ///< window cameras not compared: seen grazing
};
/// `window` in the order to try (the farthest in time first: a mover has left its place there,
/// so a real one is usually confirmed by the first camera).
Decision decide(const CameraView& ref, const std::vector<const CameraView*>& window,
                const Eigen::Vector3d& world, const ImageParams& p,
                const Eigen::Vector3d& normal = Eigen::Vector3d::Zero());

/// The object vote (DESIGN §3): an object of `cells` cells, in the order to compare them
/// (extremes first), stays moving iff at least `changed_fraction` of its compared cells look
/// changed (Decision::confirmed; at least one); a cell neither changed nor similar (unseen, too few
/// views) does not vote. At most `max_cells` cells are compared, cell j * cells / k for j < k; the
/// vote stops once the cells left cannot change it. `decide_cell(i)` decides cell i.
struct ObjectVote {
  enum class Outcome : uint8_t { kUnseen, kMoving, kStatic };
  Outcome outcome = Outcome::kUnseen;  ///< kUnseen: no cell voted, the laser label stands
  std::size_t compared = 0;            ///< cells decided
  std::size_t changed = 0, similar = 0;
  Verdict changed_by = Verdict::kUnseen;  ///< the first changed cell's verdict
  bool used_depth = false;                ///< some similar cell needed the depth test
  std::size_t grazing = 0;                ///< (cell, camera) pairs not compared: seen grazing
};
ObjectVote voteObject(std::size_t cells, double changed_fraction, int max_cells,
                      const std::function<Decision(std::size_t)>& decide_cell);

/// Whether the point is in its own scan's view `ref`: in the image with its whole patch, not
/// occluded by a nearer return (the first condition of `seen`).
bool visibleIn(const CameraView& ref, const Eigen::Vector3d& world, const ImageParams& p);

/// The overlay of `--save-overlays`: the scan's points over its image, static green, moving red,
/// relabelled static by the camera yellow. `kind` per point: 0 skip, 1 static, 2 moving,
/// 3 relabelled; `points` in the lidar frame.
cv::Mat drawOverlay(const CameraView& v, const std::vector<PointXYZI>& points,
                    const Eigen::Isometry3d& pose, const std::vector<uint8_t>& kind);

}  // namespace cleanmap::vision
