// SPDX-License-Identifier: BSD-3-Clause
// DESIGN §2b: the moving-point test of one point against the scans of its window.
#pragma once
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "cleanmap/core/beam_index.h"
#include "cleanmap/core/dempster_shafer.h"

namespace cleanmap {

/// What the test needs of a window scan: its beams and where it was taken.
struct WindowScan {
  const BeamIndex* beams = nullptr;
  Eigen::Isometry3d world_to_sensor = Eigen::Isometry3d::Identity();
  /// m^2; pose error of this scan relative to the scan being decided (0: given poses). A return
  /// at P's range within it keeps the scan from voting empty (MovingTest::scanMass).
  double pose_noise2 = 0.0;
  /// rad; the elevation step between this scan's rings where it exceeds the beam cone (a sparse
  /// lidar: 16 or 32 rings), 0 otherwise. A return at P's range on the rings just above or below
  /// P's direction keeps the scan from voting empty (MovingTest::scanMass, DESIGN §2b); where its
  /// cone holds no beam, the rings around P may vote (DsParams::ring_vote).
  double ring_gap = 0.0;
  /// Scans from P's own scan to this one (negative: before it). The empty-run rule
  /// (DsParams::empty_run) reads each side of the window from its far end; 0 = not known.
  int offset = 0;
  /// rad; the azimuth step between this scan's columns where it is clearly coarser than the
  /// HDL-64E's (kCoarseColumnsDeg: an Ouster at 1024 columns), 0 otherwise. Of P's own scan:
  /// MovingTest::edgesOf, kColumnIsolated; of the others: their beams' spread, at least
  /// MovingTest::kColumnSpread of it (DESIGN §2b, "Coarse columns' beams spread over their
  /// step").
  double column_step = 0.0;
};

// One per worker thread: aligned to a cache line so workers never share one (issue #16).
struct alignas(64) MovingTestStats {
  std::size_t total_conflicts = 0;    ///< Dempster combinations with K = 1 (set to unknown)
  std::size_t no_evidence = 0;        ///< points that no window scan saw (all unknown)
  std::size_t conflicting_scans = 0;  ///< empty scan votes made unknown (DsParams::scan_conflict)
  std::size_t ring_votes = 0;     ///< empty votes of a sparse scan's rings (MovingTest::ringVote)
  std::size_t scans_visited = 0;  ///< (point, window scan) pairs looked up
  std::size_t beams = 0;          ///< beams inside the cone, each a beam mass (Eq. 2-5)
  std::size_t early = 0;          ///< points decided before the last window scan
  std::size_t points = 0;         ///< points tested (isMoving / windowMass calls)
};

/// How the beam masses are computed: kFast (the default) evaluates a batch of beams on vector
/// lanes with fast::expNeg / fast::erfc; kReference calls libm per beam (BeamModel::beamFloat).
/// Both gave byte-identical labels on the three labelled sets; a test on real scans bounds the
/// decisions that may differ (MovingTest.FastBeamMathDecidesAsLibmOnRealScans).
enum class BeamMath { kFast, kReference };

/// Where P's own scan shows the surface ending at P (issue #15, sparse lidars): the ring just
/// above P's direction returns nowhere near P's range (kTopEdge), or the ring just below returns
/// nowhere near it (kBottomEdge). MovingTest::edgesOf. kFlatSurface: P lies on a flat surface of
/// its own scan (GrazingStretches::flat): a window scan's beam that grazes a flat surface of its
/// own where it passes P does not vote (DESIGN §2b, grazing beams). kColumnIsolated: P's own
/// scan, whose columns are coarse (WindowScan::column_step), returns from beyond P in the
/// neighbouring columns on both sides: P lies on something narrower than a column step, which
/// another scan's columns may straddle, so no window scan votes at P (DESIGN §2b, "Coarse
/// columns").
enum EdgeBits : uint8_t { kTopEdge = 1, kBottomEdge = 2, kFlatSurface = 4, kColumnIsolated = 8 };

class MovingTest {
 public:
  explicit MovingTest(const DsParams& p, BeamMath math = BeamMath::kFast);

  /// m(P, S_i) = (+)_Q m'(P, Q) over the beams of S_i within search radius of O_i->P (Eq. 6);
  /// unknown where that is empty but the scan's own beams conflict (DsParams::scan_conflict).
  /// A sparse scan with no beam near P may vote through its rings around P (DsParams::ring_vote).
  /// `edges`: P's EdgeBits, as isMoving's.
  ds::Mass scanMass(const Eigen::Vector3d& p_world, const WindowScan& s, double* range_p,
                    MovingTestStats* stats, uint8_t edges = 0) const;
  /// Window decision: Dempster combination (Eq. 6) of the discretised scan masses (Eq. 8-10).
  ds::Mass windowMass(const Eigen::Vector3d& p_world, const std::vector<WindowScan>& window,
                      MovingTestStats* stats) const;
  /// ds::isMoving(windowMass(...)), but stops visiting scans once the rest of the window cannot
  /// change the decision (see the .cpp); the statistics then cover the scans visited.
  /// `edges` (edgesOf of P in its own scan): beams that pass P on an edge's open side are left
  /// out, so they vote neither way. `empty_run`: where the votes say static, P is still moving
  /// if one side of the window has an empty run (DsParams::empty_run, DESIGN §2b); `by_run`, if
  /// given, is set to whether that run alone made P moving.
  bool isMoving(const Eigen::Vector3d& p_world, const std::vector<WindowScan>& window,
                MovingTestStats* stats, uint8_t edges = 0, bool empty_run = false,
                bool* by_run = nullptr) const;
  /// Whether one side of the window votes empty from its far end (DsParams::empty_run, DESIGN
  /// §2b, "Empty runs"), whatever the votes of the whole window say; false where that is off.
  bool hasEmptyRun(const Eigen::Vector3d& p_world, const std::vector<WindowScan>& window,
                   MovingTestStats* stats, uint8_t edges = 0) const;
  /// Whether a sparse scan (s.ring_gap wider than the cone) returns at P's range from the rings
  /// around P: a beam within the cone in azimuth and one ring step in elevation whose return
  /// lies within max(2 sigma, d * gap) of P's range d, as edgesOf's. A place between two rings
  /// that scanMass leaves unknown (no beam in its cone) on a surface those rings meet. False for
  /// dense scans.
  bool ringsReturnAt(const Eigen::Vector3d& p_world, const WindowScan& s) const;
  /// EdgeBits of P (`p`, in the sensor frame of its own scan `own`) where that scan's rings lie
  /// further apart than the beam cone (own.ring_gap); 0 for dense lidars. A ring continues P's
  /// surface if it returns within the cone in azimuth, one ring step (0.5-1.5 gaps) away in
  /// elevation, and within max(2 sigma, d * gap) of P's range d (a surface at most 45 degrees
  /// from facing the ray). Where it does not, the surface ends between the two rings, at a
  /// height this scan cannot tell: a beam of another scan passing P on that side may pass
  /// over the edge of a static object (DESIGN §2b).
  /// With coarse columns (own.column_step > 0), also kColumnIsolated where the returns of P's
  /// ring in the nearest column on each side (0.5-1.5 steps away in azimuth) lie beyond P by
  /// more than max(2 sigma, d * step) plus what the other side comes nearer than P (a surface
  /// seen obliquely recedes on one side as far as it approaches on the other), or are missing.
  uint8_t edgesOf(const Eigen::Vector3f& p, const WindowScan& own) const;
  double searchRadius() const { return radius_; }
  /// A window scan's beam spread is at least this share of its column step where its columns
  /// are coarse (WindowScan::column_step): an Ouster at 512 columns (0.70 degrees) spreads over
  /// 0.0049 rad instead of lambda_theta's 0.0035, its nearest beams half a column step (1.25 of
  /// that spread) from P's direction at most; at 1024 columns and finer lambda_theta stays.
  static constexpr double kColumnSpread = 0.4;
  /// The order in which to test points, given in the sensor frame of their scan (issue #16): in
  /// columns of azimuth two beam-index bins wide, bottom to top in each (ties by index), so that
  /// consecutive tests look up the same few bins of every window scan while they are in cache.
  /// A permutation of [0, points.size()); each point's answer does not depend on it.
  std::vector<uint32_t> testOrder(const std::vector<Eigen::Vector3f>& points) const;

 private:
  // The window's combined mass in `acc`; with stop_early, the decision once it cannot change
  // (acc is then partial).
  std::optional<bool> combineWindow(const Eigen::Vector3d& p_world,
                                    const std::vector<WindowScan>& window, MovingTestStats* stats,
                                    bool stop_early, ds::Mass& acc, uint8_t edges = 0,
                                    int8_t* votes = nullptr) const;
  // P as a window scan sees it: in its sensor frame (pl, d = |pl|), |OP| / |OB| (ratio), and
  // whether the scan can vote (beams, P not at the sensor). view() sets every field; none has a
  // default, so the test's per-point buffers of 64 are not cleared on every call (issue #16).
  struct ScanView {
    Eigen::Vector3d pl;
    double d, ratio;
    bool seen;
  };
  ScanView view(const Eigen::Vector3d& p_world, const WindowScan& s) const;
  // A seen scan's discretised mass at P (Eq. 8-10), counted as a visit.
  ds::Mass discreteMass(const ScanView& v, const WindowScan& s, MovingTestStats* stats,
                        uint8_t edges) const;
  // A scan's vote (kEmpty, kOccupied, kUnknown) from its discretised mass.
  static constexpr int8_t kEmpty = 1, kOccupied = -1, kUnknown = 0, kNotCast = 2;
  static int8_t voteOf(const ds::Mass& dm) {
    return dm.e > 0 ? kEmpty : (dm.o > 0 ? kOccupied : kUnknown);
  }
  // The vote of window scan s, as combineWindow casts it.
  int8_t vote(const Eigen::Vector3d& p_world, const WindowScan& s, MovingTestStats* stats,
              uint8_t edges) const;
  // DsParams::empty_run: whether one side of the window votes empty from its far end
  // (`votes`: those combineWindow cast, kNotCast for the others).
  bool emptyRun(const Eigen::Vector3d& p_world, const std::vector<WindowScan>& window,
                int8_t* votes, MovingTestStats* stats, uint8_t edges) const;
  // scanMass with P already in the scan's sensor frame (pl, |pl| = d > 0): combineWindow has
  // both from its visit order.
  ds::Mass scanMassAt(const Eigen::Vector3d& pl, double d, const WindowScan& s,
                      MovingTestStats* stats, uint8_t edges = 0) const;
  // Issue #15: the empty mass a sparse scan's rings around P give it (0: no vote; DESIGN §2b).
  double ringVote(const Eigen::Vector3f& dir, float d, const WindowScan& s) const;
  static constexpr float kRingFront = 1.0f;  // m; see ringVote
  // Where the rings of sparse scan s around P return at P's range, lo..hi off P's direction in
  // elevation (edgesOf, ringsReturnAt): kAbove | kBelow.
  static constexpr uint8_t kAbove = 1, kBelow = 2;
  uint8_t ringsAtRange(const Eigen::Vector3f& dir, float d, const Eigen::Vector3f& east,
                       const Eigen::Vector3f& up, const WindowScan& s, float lo, float hi) const;
  // edgesOf's kColumnIsolated of P (direction `dir`, range d, axes east / up) in its own scan.
  bool columnIsolated(const Eigen::Vector3f& dir, float d, const Eigen::Vector3f& east,
                      const Eigen::Vector3f& up, const WindowScan& own) const;
  DsParams p_;
  BeamMath math_;
  ds::BeamModel model_;
  double radius_;
  double r_far_;  // beyond this r (P far behind Q) a beam gives u = 1 to double precision
  // Upper bounds of a scan's vote weight -ln(1 - l) over cells of |OP| / |OB| (combineWindow).
  static constexpr int kWeightCells = 256;
  std::array<double, kWeightCells + 1> w_bound_{};
};

}  // namespace cleanmap
