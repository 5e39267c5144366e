// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/vision/image_validation.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

#include "cleanmap/core/error.h"

namespace cleanmap::vision {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

int clampInt(double v, int lo, int hi) {
  return static_cast<int>(std::clamp(std::lround(v), long(lo), long(hi)));
}

// Square of side `side` centred at px.
cv::Rect squareAt(const Eigen::Vector2d& px, int side) {
  return {static_cast<int>(std::floor(px.x() - 0.5 * side + 0.5)),
          static_cast<int>(std::floor(px.y() - 0.5 * side + 0.5)), side, side};
}

}  // namespace

CameraView makeCameraView(const cv::Mat& bgr, const std::vector<PointXYZI>& points,
                          const Eigen::Isometry3d& pose, const PinholeCamera& cam,
                          std::size_t index, const std::string& source, int radius) {
  if (bgr.empty() || bgr.type() != CV_8UC3)
    throw Error(source, "the camera image is not an 8-bit, 3-channel image");
  if (cam.width > 0 && (bgr.cols != cam.width || bgr.rows != cam.height))
    throw Error(source, "the camera image is " + std::to_string(bgr.cols) + "x" +
                            std::to_string(bgr.rows) + " but the calibration (" + cam.name +
                            ") is for " + std::to_string(cam.width) + "x" +
                            std::to_string(cam.height));
  CameraView v;
  v.image = bgr;
  v.index = index;
  const Eigen::Isometry3d opt_lidar = cam.opticalFromLidar();
  v.optical_from_world = opt_lidar * pose.inverse();
  v.centre = pose * opt_lidar.inverse().translation();
  const Eigen::Matrix3d K = cam.K();
  v.fx = K(0, 0);
  v.fy = K(1, 1);
  v.cx = K(0, 2);
  v.cy = K(1, 2);
  {  // The grey pyramid for the photometric alignment (alignment.h).
    cv::Mat g, g32;
    cv::cvtColor(bgr, g, cv::COLOR_BGR2GRAY);
    g.convertTo(g32, CV_32F, 1.0 / 255);
    v.grey.resize(4);
    cv::pyrDown(g32, v.grey[1]);
    cv::pyrDown(v.grey[1], v.grey[2]);
    cv::pyrDown(v.grey[2], v.grey[3]);
  }
  // The sparse depth map: the nearest return per pixel (SPEC §3, depth test), as a full image
  // for the alignment (released after it) and row by row for the window.
  v.sparse = cv::Mat(bgr.rows, bgr.cols, CV_32F, cv::Scalar(kInf));
  const Eigen::Matrix3f R = opt_lidar.linear().cast<float>();
  const Eigen::Vector3f t = opt_lidar.translation().cast<float>();
  std::size_t hits = 0;
  for (const auto& p : points) {
    const Eigen::Vector3f q = R * p.xyz() + t;
    if (q.z() < 0.3f) continue;
    const int u = static_cast<int>(std::floor(v.fx * q.x() / q.z() + v.cx));
    const int w = static_cast<int>(std::floor(v.fy * q.y() / q.z() + v.cy));
    if (u < 0 || w < 0 || u >= bgr.cols || w >= bgr.rows) continue;
    float& d = v.sparse.at<float>(w, u);
    d = std::min(d, q.norm());
    ++hits;
  }
  auto sd = std::make_shared<SparseDepth>();
  sd->rows = bgr.rows;
  sd->cols = bgr.cols;
  sd->start.reserve(std::size_t(bgr.rows) + 1);
  sd->col.reserve(hits);
  sd->dist.reserve(hits);
  for (int y = 0; y < bgr.rows; ++y) {
    sd->start.push_back(static_cast<int32_t>(sd->col.size()));
    const float* row = v.sparse.ptr<float>(y);
    for (int x = 0; x < bgr.cols; ++x)
      if (row[x] != kInf) {
        sd->col.push_back(static_cast<uint16_t>(x));
        sd->dist.push_back(row[x]);
      }
  }
  sd->start.push_back(static_cast<int32_t>(sd->col.size()));
  v.returns = std::move(sd);
  v.radius = radius;
  return v;
}

cv::Mat SparseDepth::dense(const cv::Rect& r) const {
  cv::Mat m(r.height, r.width, CV_32F, cv::Scalar(kInf));
  const int x0 = std::max(r.x, 0), x1 = std::min(r.x + r.width, cols);
  for (int y = std::max(r.y, 0); y < std::min(r.y + r.height, rows); ++y) {
    const auto b = col.begin() + start[std::size_t(y)], e = col.begin() + start[std::size_t(y) + 1];
    float* out = m.ptr<float>(y - r.y);
    for (auto it = std::lower_bound(b, e, x0); it != e && *it < x1; ++it)
      out[*it - r.x] = dist[std::size_t(it - col.begin())];
  }
  return m;
}

float SparseDepth::minIn(int y0, int y1, int x0, int x1) const {
  float best = kInf;
  for (int y = y0; y <= y1; ++y) {
    const auto b = col.begin() + start[std::size_t(y)], e = col.begin() + start[std::size_t(y) + 1];
    for (auto it = std::lower_bound(b, e, x0); it != e && *it <= x1; ++it)
      best = std::min(best, dist[std::size_t(it - col.begin())]);
  }
  return best;
}

cv::Mat depthPatch(const CameraView& v, const cv::Rect& r) {
  const int k = v.radius;
  if (k <= 0) return v.returns->dense(r);
  // The rectangle grown by the disk: every pixel the disk of a pixel of r reaches, +inf outside
  // the image (the whole map's border), so the erosion inside r is the whole map's.
  const cv::Mat grown =
      v.returns->dense(cv::Rect(r.x - k, r.y - k, r.width + 2 * k, r.height + 2 * k));
  cv::Mat out;
  cv::erode(grown, out,
            cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * k + 1, 2 * k + 1)),
            cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(kInf));
  return out(cv::Rect(k, k, r.width, r.height));
}

float nearestReturn(const CameraView& v, const Eigen::Vector2d& px) {
  const int u = static_cast<int>(px.x()), w = static_cast<int>(px.y());
  const int rows = v.image.rows, cols = v.image.cols;
  const int y0 = std::max(0, w - 1), y1 = std::min(rows - 1, w + 1);
  const int x0 = std::max(0, u - 1), x1 = std::min(cols - 1, u + 1);
  if (v.sparse.empty()) return v.returns->minIn(y0, y1, x0, x1);
  float best = kInf;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) best = std::min(best, v.sparse.at<float>(y, x));
  return best;
}

std::optional<Projection> project(const CameraView& v, const Eigen::Vector3d& world) {
  const Eigen::Vector3d q = v.optical_from_world * world;
  if (q.z() <= 0.3) return std::nullopt;
  Projection pr;
  pr.px = {v.fx * q.x() / q.z() + v.cx, v.fy * q.y() / q.z() + v.cy};
  if (pr.px.x() < 0 || pr.px.y() < 0 || pr.px.x() >= v.image.cols || pr.px.y() >= v.image.rows)
    return std::nullopt;
  pr.distance = q.norm();
  return pr;
}

bool isTextured(const cv::Mat& patch, double min_std, const cv::Mat& mask) {
  cv::Scalar mean, sd;
  cv::meanStdDev(patch, mean, sd, mask);
  for (int c = 0; c < patch.channels(); ++c)
    if (sd[c] < 1e-3) return false;  // a flat channel: NCC is undefined there (paper §III)
  cv::Mat grey;
  cv::transform(patch, grey, cv::Matx13f(1.f / 3, 1.f / 3, 1.f / 3));
  cv::meanStdDev(grey, mean, sd, mask);
  return sd[0] > min_std;
}

namespace {

// The largest NCC of one channel of `t` slid over `r` (CV_32F), over the pixels of `mask` (CV_8U
// or empty), written out: for small patches it is several times faster than OpenCV's masked
// matchTemplate, which goes through DFTs (issue #16). A flat window of the region correlates -1.
double maxNccDirect(const cv::Mat& r, const cv::Mat& t, const cv::Mat& mask) {
  std::vector<int> at;  // offsets of the template pixels (region layout)
  std::vector<double> tv;
  double st = 0, stt = 0;
  for (int y = 0; y < t.rows; ++y)
    for (int x = 0; x < t.cols; ++x) {
      if (!mask.empty() && !mask.at<uchar>(y, x)) continue;
      const double v = t.at<float>(y, x);
      at.push_back(y * r.cols + x);
      tv.push_back(v);
      st += v;
      stt += v * v;
    }
  const double n = double(at.size());
  const double tvar = stt - st * st / n;
  double best = -1.0;
  if (n < 2 || !(tvar > 0)) return best;
  for (int sy = 0; sy + t.rows <= r.rows; ++sy)
    for (int sx = 0; sx + t.cols <= r.cols; ++sx) {
      const float* base = r.ptr<float>(sy) + sx;
      double sr = 0, srr = 0, str = 0;
      for (std::size_t k = 0; k < at.size(); ++k) {
        const double v = base[at[k]];
        sr += v;
        srr += v * v;
        str += tv[k] * v;
      }
      const double rvar = srr - sr * sr / n;
      if (!(rvar > 1e-12 * n)) continue;  // flat window
      best = std::max(best, (str - st * sr / n) / std::sqrt(tvar * rvar));
    }
  return best;
}

// The DFT of `a` (CV_32F) zero-padded to `ds` (CCS packed).
cv::Mat paddedSpectrum(const cv::Mat& a, const cv::Size& ds) {
  cv::Mat padded = cv::Mat::zeros(ds, CV_32F), f;
  a.copyTo(padded(cv::Rect(0, 0, a.cols, a.rows)));
  cv::dft(padded, f, 0, a.rows);
  return f;
}

// The same through three correlations computed with DFTs (issue #16): OpenCV's masked
// matchTemplate does more of them, one forward transform per correlation. `m` is the mask as
// 0 / 1 floats (n of them set), `mspec` its spectrum at size `ds`. The template is centred on its
// masked mean (the numerator is then one correlation, without cancellation) and the region on
// its own mean (the NCC does not change; the sums' rounding shrinks). A window whose variance is
// below the transforms' rounding (1e-6 of the region's energy) is flat: -1, as OpenCV's NaN.
double maxNccSpectral(const cv::Mat& r, const cv::Mat& t, const cv::Mat& m, const cv::Mat& mspec,
                      double n, const cv::Size& ds) {
  const int w = r.cols - t.cols + 1, h = r.rows - t.rows + 1;
  const double tmean = cv::sum(t.mul(m))[0] / n;
  const cv::Mat tc = (t - tmean).mul(m);
  const double tvar = cv::sum(tc.mul(tc))[0];
  if (n < 2 || !(tvar > 0)) return -1.0;
  const cv::Mat rc = r - cv::mean(r)[0];
  const cv::Mat rc2 = rc.mul(rc);
  const double floor = 1e-6 * cv::sum(rc2)[0];
  const auto correlate = [&](const cv::Mat& a, const cv::Mat& b) {
    cv::Mat prod, out;
    cv::mulSpectrums(a, b, prod, 0, true);
    cv::dft(prod, out, cv::DFT_INVERSE | cv::DFT_SCALE | cv::DFT_REAL_OUTPUT, h);
    return out;
  };
  const cv::Mat rs = paddedSpectrum(rc, ds), r2s = paddedSpectrum(rc2, ds);
  const cv::Mat num = correlate(rs, paddedSpectrum(tc, ds)), sr = correlate(rs, mspec),
                srr = correlate(r2s, mspec);
  double best = -1.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double s1 = sr.at<float>(y, x), s2 = srr.at<float>(y, x);
      const double rvar = s2 - s1 * s1 / n;
      if (!(rvar > floor) || !(rvar > 1e-12 * n)) continue;  // flat window
      best = std::max(best, num.at<float>(y, x) / std::sqrt(tvar * rvar));
    }
  return best;
}

}  // namespace

double colourError(const cv::Mat& tmpl, const cv::Mat& region, const cv::Mat& mask,
                   double stop_at) {
  cv::Mat t[3], r[3], res;
  cv::split(tmpl, t);
  cv::split(region, r);
  // Shifts x template pixels: below this the sums written out are faster than the DFTs.
  constexpr double kDirectWork = 60000;
  const double shifts = double(region.rows - tmpl.rows + 1) * (region.cols - tmpl.cols + 1);
  const bool direct = shifts * tmpl.rows * tmpl.cols <= kDirectWork;
  cv::Mat m, mspec;  // the mask's spectrum, shared by the channels (maxNccSpectral)
  double n = 0;
  cv::Size ds;
  if (!direct && !mask.empty()) {
    cv::Mat(mask != 0).convertTo(m, CV_32F, 1.0 / 255);  // any value set (OpenCV's 0 / 1 too)
    n = cv::countNonZero(mask);
    ds = cv::Size(cv::getOptimalDFTSize(region.cols), cv::getOptimalDFTSize(region.rows));
    mspec = paddedSpectrum(m, ds);
  }
  double worst = 0;
  for (int c = 0; c < tmpl.channels(); ++c) {
    double hi = -1.0;
    if (direct) {
      hi = maxNccDirect(r[c], t[c], mask);
    } else if (!mask.empty()) {
      hi = maxNccSpectral(r[c], t[c], m, mspec, n, ds);
    } else {
      cv::matchTemplate(r[c], t[c], res, cv::TM_CCOEFF_NORMED, mask);
      cv::patchNaNs(res, -1.0);  // a flat window of the region: no correlation
      double lo = 0;
      cv::minMaxLoc(res, &lo, &hi);
    }
    worst = std::max(worst, 1.0 - std::min(hi, 1.0));
    if (worst >= stop_at) break;  // a channel already differs: the verdict is settled
  }
  return worst;
}

std::optional<double> depthError(const cv::Mat& tmpl, double d_t, const cv::Mat& region, double d_r,
                                 double stop_below) {
  const int n = tmpl.rows * tmpl.cols;
  const double inv = 1.0 / d_t;
  // Each pixel's relative depth once, not once per shift (issue #16; the same values, summed in
  // the same order): the template's pixels with a return, the region's (NaN: none).
  struct Px {
    int offset;  // y * region.cols + x
    double e;
  };
  std::vector<Px> t;
  t.reserve(static_cast<std::size_t>(n));
  for (int y = 0; y < tmpl.rows; ++y) {
    const float* a = tmpl.ptr<float>(y);
    for (int x = 0; x < tmpl.cols; ++x)
      if (std::isfinite(a[x]))
        t.push_back({y * region.cols + x, std::clamp((a[x] - d_t) * inv, -1.0, 1.0)});
  }
  std::vector<double> r(static_cast<std::size_t>(region.rows) * region.cols);
  for (int y = 0; y < region.rows; ++y) {
    const float* b = region.ptr<float>(y);
    for (int x = 0; x < region.cols; ++x)
      r[std::size_t(y) * region.cols + x] = std::isfinite(b[x])
                                                ? std::clamp((b[x] - d_r) * inv, -1.0, 1.0)
                                                : std::numeric_limits<double>::quiet_NaN();
  }
  std::optional<double> best;
  if (2 * t.size() < std::size_t(n)) return best;  // too few at every shift
  for (int sy = 0; sy + tmpl.rows <= region.rows; ++sy)
    for (int sx = 0; sx + tmpl.cols <= region.cols; ++sx) {
      const double* base = r.data() + std::size_t(sy) * region.cols + sx;
      double sum = 0;
      int used = 0;
      for (const Px& p : t) {
        const double eb = base[p.offset];
        if (std::isnan(eb)) continue;
        sum += (p.e - eb) * (p.e - eb);
        ++used;
      }
      if (2 * used < n) continue;
      const double mse = sum / used;
      if (!best || mse < *best) best = mse;
      if (mse < stop_below) return best;
    }
  return best;
}

std::optional<Eigen::Vector3d> surfaceNormal(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 6) return std::nullopt;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& x : points) mean += x;
  mean /= double(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& x : points) cov += (x - mean) * (x - mean).transpose();
  cov /= double(points.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);  // eigenvalues ascending
  const Eigen::Vector3d ev = es.eigenvalues();
  if (!(ev[1] >= 0.05 * 0.05) || ev[0] > 0.1 * ev[1]) return std::nullopt;
  return es.eigenvectors().col(0).normalized();
}

bool grazing(const Eigen::Vector3d& centre, const Eigen::Vector3d& world,
             const Eigen::Vector3d& normal, double max_incidence_deg) {
  if (max_incidence_deg >= 90 || normal.squaredNorm() == 0) return false;
  const Eigen::Vector3d ray = world - centre;
  const double n = ray.norm();
  return n > 0 && std::abs(normal.dot(ray)) < std::cos(max_incidence_deg * M_PI / 180) * n;
}

namespace {

// The point in its own scan's camera: projected, not occluded (a nearer return at the pixel hides
// it), its patch of side b = h f / d (SPEC §3) inside the image. Nullopt otherwise.
struct RefPatch {
  Projection pk;
  int bk = 0;
  cv::Rect tk;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // the surface's, world frame (zero: unknown)
  cv::Mat depth;                                     // the depth test's map over tk
};
std::optional<RefPatch> refPatch(const CameraView& ref, const Eigen::Vector3d& world,
                                 const ImageParams& p, const Eigen::Vector3d& normal,
                                 bool with_depth = true) {
  const auto pk = project(ref, world);
  if (!pk || nearestReturn(ref, pk->px) < pk->distance - p.occlusion) return std::nullopt;
  RefPatch r{
      *pk, clampInt(p.patch_height * ref.fx / pk->distance, p.min_patch, 512), {}, normal, {}};
  r.tk = squareAt(pk->px, r.bk);
  if ((r.tk & cv::Rect(0, 0, ref.image.cols, ref.image.rows)) != r.tk) return std::nullopt;
  if (with_depth) r.depth = depthPatch(ref, r.tk);
  return r;
}

Verdict compareWith(const CameraView& ref, const RefPatch& rp, const CameraView& other,
                    const Eigen::Vector3d& world, const ImageParams& p) {
  const auto pl = project(other, world);
  if (!pl || nearestReturn(other, pl->px) < pl->distance - p.occlusion) return Verdict::kUnseen;
  // Seen grazing by either camera: foreshortened and textured below the pixel, its look depends
  // on the viewpoint (simulated street, exact poses: 57 % of the colour comparisons of static
  // cells seen grazing differed, 27 % of the others; DESIGN §3). Not compared.
  if (grazing(ref.centre, world, rp.normal, p.max_incidence_deg) ||
      grazing(other.centre, world, rp.normal, p.max_incidence_deg))
    return Verdict::kGrazing;
  const Projection* pk = &rp.pk;
  const int bk = rp.bk;
  const cv::Rect& tk = rp.tk;
  // The patch side and the search margin in the other image (SPEC §3).
  const int bl = clampInt(p.patch_height * other.fx / pl->distance, p.min_patch, 512);
  const int ml = clampInt(p.search_margin * other.fx / pl->distance, 0, 4 * bl);
  const cv::Rect pl_rect = squareAt(pl->px, bl);
  const cv::Rect region = cv::Rect(pl_rect.x - ml, pl_rect.y - ml, bl + 2 * ml, bl + 2 * ml) &
                          cv::Rect(0, 0, other.image.cols, other.image.rows);
  if (region.width < bl || region.height < bl) return Verdict::kUnseen;
  // The smaller patch is resized to the other's size; both are then brought to at most
  // max_patch (finer detail adds cost, not evidence).
  const int side = std::min(std::max(bk, bl), p.max_patch);
  const double sl = double(side) / bl;
  const cv::Size region_size(std::max(side, int(std::lround(region.width * sl))),
                             std::max(side, int(std::lround(region.height * sl))));
  cv::Mat tmpl, reg, patch_l, mask;
  cv::resize(ref.image(tk), tmpl, cv::Size(side, side), 0, 0, cv::INTER_AREA);
  // Only the template's pixels on the point's own surface (depth within the occlusion tolerance)
  // are compared: at a silhouette, the background behind shifts with the viewpoint (parallax)
  // and would make a static edge look changed. Too few such pixels: the whole patch (paper).
  {
    cv::Mat d;
    cv::resize(rp.depth, d, cv::Size(side, side), 0, 0, cv::INTER_NEAREST);
    const float lo = float(pk->distance - p.occlusion), hi = float(pk->distance + p.occlusion);
    mask = (d >= lo) & (d <= hi);
    if (4 * cv::countNonZero(mask) < side * side) mask = cv::Mat();
  }
  cv::resize(other.image(region), reg, region_size, 0, 0, cv::INTER_AREA);
  tmpl.convertTo(tmpl, CV_32FC3, 1.0 / 255);
  reg.convertTo(reg, CV_32FC3, 1.0 / 255);
  // The other patch itself (at the projection, no margin) for the uniformity check.
  const cv::Rect own_l = pl_rect & cv::Rect(0, 0, other.image.cols, other.image.rows);
  cv::resize(other.image(own_l), patch_l, cv::Size(side, side), 0, 0, cv::INTER_AREA);
  patch_l.convertTo(patch_l, CV_32FC3, 1.0 / 255);
  if (isTextured(tmpl, p.uniform_std, mask) && isTextured(patch_l, p.uniform_std, mask))
    return colourError(tmpl, reg, mask, p.ncc_threshold) < p.ncc_threshold
               ? Verdict::kSimilarColour
               : Verdict::kDifferentColour;
  // Depth test where a patch is uniform: the depth maps, gaps closed, each patch relative to the
  // point's own expected depth in its camera (the motion correction, DESIGN §3).
  cv::Mat dt, dr;
  cv::resize(rp.depth, dt, cv::Size(side, side), 0, 0, cv::INTER_NEAREST);
  cv::resize(depthPatch(other, region), dr, region_size, 0, 0, cv::INTER_NEAREST);
  const auto e = depthError(dt, pk->distance, dr, pl->distance, p.depth_threshold);
  if (!e) return Verdict::kUnseen;
  return *e < p.depth_threshold ? Verdict::kSimilarDepth : Verdict::kDifferentDepth;
}

}  // namespace

Verdict compareViews(const CameraView& ref, const CameraView& other, const Eigen::Vector3d& world,
                     const ImageParams& p, const Eigen::Vector3d& normal) {
  const auto rp = refPatch(ref, world, p, normal);
  return rp ? compareWith(ref, *rp, other, world, p) : Verdict::kUnseen;
}

ObjectVote voteObject(std::size_t cells, double changed_fraction, int max_cells,
                      const std::function<Decision(std::size_t)>& decide_cell) {
  ObjectVote v;
  const double f = changed_fraction;
  const std::size_t k = std::min<std::size_t>(cells, static_cast<std::size_t>(max_cells));
  std::size_t left = k;
  for (std::size_t j = 0; j < k; ++j) {
    --left;
    const Decision d = decide_cell(j * cells / k);
    ++v.compared;
    v.grazing += static_cast<std::size_t>(d.grazing);
    if (d.confirmed) {
      if (v.changed++ == 0) v.changed_by = d.decisive;
    } else if (d.relabel_static) {
      ++v.similar;
      v.used_depth = v.used_depth || d.used_depth;
    } else {
      continue;  // unseen, or seen by too few cameras: no vote
    }
    const double voters = double(v.similar + v.changed + left);
    if (v.changed > 0 && double(v.changed) >= f * voters) break;  // moving, whatever the rest say
    // (changed + x) / (voters + x) grows with x: not even all the rest changed would do.
    if (double(v.changed + left) < f * voters) break;
  }
  if (v.changed > 0 && double(v.changed) >= f * double(v.similar + v.changed))
    v.outcome = ObjectVote::Outcome::kMoving;
  else if (v.similar > 0)
    v.outcome = ObjectVote::Outcome::kStatic;
  return v;
}

bool visibleIn(const CameraView& ref, const Eigen::Vector3d& world, const ImageParams& p) {
  return refPatch(ref, world, p, Eigen::Vector3d::Zero(), false).has_value();
}

Decision decide(const CameraView& ref, const std::vector<const CameraView*>& window,
                const Eigen::Vector3d& world, const ImageParams& p, const Eigen::Vector3d& normal) {
  Decision d;
  const auto rp = refPatch(ref, world, p, normal);  // once for the whole window
  if (!rp) return d;
  for (const CameraView* v : window) {
    const Verdict vd = compareWith(ref, *rp, *v, world, p);
    d.grazing += vd == Verdict::kGrazing;
    if (vd == Verdict::kUnseen || vd == Verdict::kGrazing) continue;
    ++d.views;
    d.decisive = vd;
    d.used_depth = d.used_depth || vd == Verdict::kSimilarDepth || vd == Verdict::kDifferentDepth;
    if (vd == Verdict::kDifferentColour || vd == Verdict::kDifferentDepth) break;
  }
  d.seen = d.views > 0;
  d.confirmed = d.decisive == Verdict::kDifferentColour || d.decisive == Verdict::kDifferentDepth;
  d.relabel_static = d.views >= p.min_views && (d.decisive == Verdict::kSimilarColour ||
                                                d.decisive == Verdict::kSimilarDepth);
  return d;
}

cv::Mat drawOverlay(const CameraView& v, const std::vector<PointXYZI>& points,
                    const Eigen::Isometry3d& pose, const std::vector<uint8_t>& kind) {
  cv::Mat out = v.image.clone();
  const Eigen::Isometry3d opt_lidar = v.optical_from_world * pose;
  const cv::Scalar colour[4] = {{0, 0, 0}, {0, 200, 0}, {0, 0, 255}, {0, 255, 255}};  // BGR
  for (uint8_t pass = 1; pass <= 3; ++pass)  // moving and relabelled drawn over static
    for (std::size_t i = 0; i < points.size() && i < kind.size(); ++i) {
      if (kind[i] != pass) continue;
      const Eigen::Vector3d q = opt_lidar * points[i].xyz().cast<double>();
      if (q.z() <= 0.3) continue;
      const cv::Point px(int(v.fx * q.x() / q.z() + v.cx), int(v.fy * q.y() / q.z() + v.cy));
      if (px.x < 0 || px.y < 0 || px.x >= out.cols || px.y >= out.rows) continue;
      cv::circle(out, px, pass == 1 ? 1 : 2, colour[pass], cv::FILLED);
    }
  return out;
}

}  // namespace cleanmap::vision
