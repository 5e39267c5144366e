// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/eval/pictures.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <ostream>

#include "cleanmap/core/error.h"
#include "cleanmap/io/files.h"

namespace cleanmap::eval {
namespace {

// BGR
const cv::Vec3b kColour[] = {
    {40, 40, 230},    // TP red
    {0, 150, 255},    // FP orange
    {230, 120, 30},   // FN blue
    {150, 150, 150},  // TN grey
    {70, 70, 70},     // not scored
};

void legend(cv::Mat& img, const std::vector<std::pair<std::string, cv::Vec3b>>& items, int y0) {
  int x = 8;
  for (const auto& [text, c] : items) {
    cv::rectangle(img, {x, y0 - 9}, {x + 10, y0 + 1}, cv::Scalar(c[0], c[1], c[2]), cv::FILLED);
    cv::putText(img, text, {x + 14, y0}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(230, 230, 230),
                1, cv::LINE_AA);
    x += 16 + 8 * static_cast<int>(text.size()) + 12;
  }
}

}  // namespace

Outcome outcome(uint32_t predicted, uint32_t truth) {
  const GtClass t = gtClass(truth);
  if (t == GtClass::kIgnore || predicted == 0) return Outcome::kNotScored;
  const bool pm = gtClass(predicted) == GtClass::kMoving;
  const bool tm = t == GtClass::kMoving;
  if (pm && tm) return Outcome::kTruePositive;
  if (pm) return Outcome::kFalsePositive;
  if (tm) return Outcome::kFalseNegative;
  return Outcome::kTrueNegative;
}

cv::Mat birdsEyeView(const std::vector<PointXYZI>& points, const Labels& predicted,
                     const Labels& truth, double half_extent, const std::string& title) {
  constexpr double kRes = 0.1;  // m per pixel
  const int side = std::max(64, static_cast<int>(std::ceil(2 * half_extent / kRes)));
  const int top = 28;
  cv::Mat img(side + top, side, CV_8UC3, cv::Scalar(0, 0, 0));
  // Draw the rarer, more telling outcomes last so they are not hidden under static points.
  const Outcome order[] = {Outcome::kNotScored, Outcome::kTrueNegative, Outcome::kFalseNegative,
                           Outcome::kFalsePositive, Outcome::kTruePositive};
  const std::size_t n = std::min({points.size(), predicted.size(), truth.size()});
  for (const Outcome pass : order)
    for (std::size_t i = 0; i < n; ++i) {
      if (outcome(predicted[i], truth[i]) != pass) continue;
      // x forward = up in the picture, y left = left.
      const int u = static_cast<int>(std::floor((half_extent - points[i].y) / kRes));
      const int v = static_cast<int>(std::floor((half_extent - points[i].x) / kRes)) + top;
      if (u < 0 || u >= side || v < top || v >= side + top) continue;
      const int dot = pass == Outcome::kTrueNegative || pass == Outcome::kNotScored
                          ? 1
                          : 2;  // movers stand out
      for (int dv = 0; dv < dot && v + dv < side + top; ++dv)
        for (int du = 0; du < dot && u + du < side; ++du)
          img.at<cv::Vec3b>(v + dv, u + du) = kColour[static_cast<int>(pass)];
    }
  cv::circle(img, {side / 2, side / 2 + top}, 3, cv::Scalar(255, 255, 255), cv::FILLED);
  cv::putText(img, title, {8, 12}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
  legend(img,
         {{"TP", kColour[0]},
          {"FP", kColour[1]},
          {"FN", kColour[2]},
          {"static", kColour[3]},
          {"not scored", kColour[4]}},
         24);
  return img;
}

cv::Mat mapOverview(const std::vector<Eigen::Vector3f>& map,
                    const std::vector<Eigen::Vector3f>& leftovers, const std::string& title,
                    int max_side) {
  Eigen::Vector2f lo(0, 0), hi(1, 1);
  bool first = true;
  for (const auto* v : {&map, &leftovers})
    for (const auto& p : *v) {
      if (first) lo = hi = p.head<2>();
      first = false;
      lo = lo.cwiseMin(p.head<2>());
      hi = hi.cwiseMax(p.head<2>());
    }
  const float span = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1.0f});
  const double res = std::max(0.1, static_cast<double>(span) / max_side);  // m per pixel
  const int w = std::max(64, static_cast<int>((hi.y() - lo.y()) / res) + 1);
  const int h = std::max(64, static_cast<int>((hi.x() - lo.x()) / res) + 1);
  cv::Mat count(h, w, CV_32F, cv::Scalar(0));
  auto pix = [&](const Eigen::Vector3f& p) {
    return cv::Point(static_cast<int>((hi.y() - p.y()) / res),
                     static_cast<int>((hi.x() - p.x()) / res));
  };
  for (const auto& p : map) {
    const cv::Point q = pix(p);
    if (q.x >= 0 && q.x < w && q.y >= 0 && q.y < h) count.at<float>(q) += 1.f;
  }
  cv::Mat grey;
  cv::log(count + 1.f, count);
  double mx = 0;
  cv::minMaxLoc(count, nullptr, &mx);
  count.convertTo(grey, CV_8U, mx > 0 ? 235.0 / mx : 0.0, 0);
  const int top = 28;
  cv::Mat img(h + top, w, CV_8UC3, cv::Scalar(0, 0, 0));
  cv::Mat body = img(cv::Rect(0, top, w, h));
  cv::cvtColor(grey, body, cv::COLOR_GRAY2BGR);
  for (const auto& p : leftovers) {
    const cv::Point q = pix(p);
    if (q.x >= 0 && q.x < w && q.y >= 0 && q.y < h) body.at<cv::Vec3b>(q) = kColour[0];
  }
  cv::putText(img, title, {8, 12}, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
  legend(img, {{"clean map", {200, 200, 200}}, {"moving points left in the map", kColour[0]}}, 24);
  return img;
}

cv::Mat rocPlot(const std::vector<RocCurve>& curves, const RocCurvePoint& marked,
                const std::string& title) {
  const int W = 640, H = 520, L = 60, R = 170, T = 30, B = 50;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  // Axis ranges: the data's, padded, always starting at 0.
  double fmax = 0.01, tmin = 1.0;
  for (const auto& c : curves)
    for (const auto& p : c.points) {
      fmax = std::max(fmax, p.fpr);
      tmin = std::min(tmin, p.tpr);
    }
  fmax = std::min(1.0, fmax * 1.15);
  tmin = std::max(0.0, tmin - 0.05);
  const double tmax = 1.0;
  auto to = [&](double fpr, double tpr) {
    return cv::Point(L + static_cast<int>((W - L - R) * fpr / fmax),
                     H - B - static_cast<int>((H - T - B) * (tpr - tmin) / (tmax - tmin)));
  };
  cv::rectangle(img, to(0, tmax), to(fmax, tmin), cv::Scalar(0, 0, 0), 1);
  char buf[64];
  for (int k = 0; k <= 4; ++k) {
    const double f = fmax * k / 4, t = tmin + (tmax - tmin) * k / 4;
    std::snprintf(buf, sizeof buf, "%.3f", f);
    cv::putText(img, buf, to(f, tmin) + cv::Point(-14, 16), cv::FONT_HERSHEY_SIMPLEX, 0.38,
                {0, 0, 0}, 1, cv::LINE_AA);
    std::snprintf(buf, sizeof buf, "%.2f", t);
    cv::putText(img, buf, to(0, t) + cv::Point(-40, 4), cv::FONT_HERSHEY_SIMPLEX, 0.38, {0, 0, 0},
                1, cv::LINE_AA);
  }
  cv::putText(img, "false positive rate", {L + 120, H - 12}, cv::FONT_HERSHEY_SIMPLEX, 0.45,
              {0, 0, 0}, 1, cv::LINE_AA);
  cv::putText(img, "TPR", {8, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.45, {0, 0, 0}, 1, cv::LINE_AA);
  cv::putText(img, title, {L, 18}, cv::FONT_HERSHEY_SIMPLEX, 0.45, {0, 0, 0}, 1, cv::LINE_AA);
  const cv::Scalar palette[] = {{200, 80, 30},  {40, 160, 40}, {30, 30, 220},
                                {160, 40, 160}, {0, 140, 200}, {90, 90, 90}};
  for (std::size_t c = 0; c < curves.size(); ++c) {
    const cv::Scalar col = palette[c % 6];
    std::vector<cv::Point> pts;
    for (const auto& p : curves[c].points) pts.push_back(to(p.fpr, p.tpr));
    if (pts.size() > 1) cv::polylines(img, pts, false, col, 2, cv::LINE_AA);
    for (const auto& q : pts) cv::circle(img, q, 3, col, cv::FILLED, cv::LINE_AA);
    const cv::Point lg(W - R + 12, T + 18 + 20 * static_cast<int>(c));
    cv::line(img, lg, lg + cv::Point(20, 0), col, 2);
    cv::putText(img, curves[c].label, lg + cv::Point(26, 4), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                {0, 0, 0}, 1, cv::LINE_AA);
  }
  cv::circle(img, to(marked.fpr, marked.tpr), 8, cv::Scalar(0, 0, 0), 2, cv::LINE_AA);
  const cv::Point lg(W - R + 22, T + 18 + 20 * static_cast<int>(curves.size()));
  cv::circle(img, lg, 7, cv::Scalar(0, 0, 0), 2, cv::LINE_AA);
  cv::putText(img, "default", lg + cv::Point(16, 4), cv::FONT_HERSHEY_SIMPLEX, 0.4, {0, 0, 0}, 1,
              cv::LINE_AA);
  return img;
}

void writePng(const std::string& path, const cv::Mat& image) {
  std::vector<uchar> buf;
  if (!cv::imencode(".png", image, buf)) throw Error(path, "PNG encoding failed");
  io::writeFileAtomic(path, [&](std::ostream& os) {
    os.write(reinterpret_cast<const char*>(buf.data()), static_cast<std::streamsize>(buf.size()));
  });
}

}  // namespace cleanmap::eval
