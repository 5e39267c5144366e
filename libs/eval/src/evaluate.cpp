// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/eval/evaluate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/eval/pictures.h"
#include "cleanmap/io/config.h"
#include "cleanmap/io/files.h"
#include "cleanmap/io/kitti.h"
#include "cleanmap/io/objects.h"
#include "cleanmap/io/output.h"
#include "cleanmap/io/pcd.h"

namespace fs = std::filesystem;

namespace cleanmap::eval {
namespace {

constexpr double kObjectMargin = 0.2;          // m; box inflation when assigning points to objects
constexpr std::size_t kMaxLeftovers = 200000;  // points drawn in the map overview

RunTime readRunReport(const std::string& path) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(io::readTextFile(path));
  } catch (const nlohmann::json::exception& e) {
    throw Error(path, std::string("not a JSON run report: ") + e.what());
  }
  RunTime rt;
  try {
    rt.threads = j.value("threads", 0);
    rt.peak_rss_mib = j.value("peak_rss_mib", 0.0);
    rt.wall_s = j.value("wall_s", 0.0);
    rt.scans = j.value("scans", std::size_t{0});
    if (!j.contains("timing_per_scan"))
      throw Error(path, "no timing_per_scan: not a cleanmap run report");
    const auto& t = j.at("timing_per_scan");
    if (t.contains("total"))
      rt.stages.push_back({"total", t["total"].at("median_ms").get<double>(),
                           t["total"].at("p95_ms").get<double>()});
    for (const auto& [name, v] : t.items())
      if (name != "total")
        rt.stages.push_back({name, v.at("median_ms").get<double>(), v.at("p95_ms").get<double>()});
  } catch (const nlohmann::json::exception& e) {
    throw Error(path, std::string("malformed run report: ") + e.what());
  }
  return rt;
}

nlohmann::json countsJson(const MosCounts& c) {
  return {{"tp", c.tp}, {"fp", c.fp},           {"fn", c.fn},
          {"tn", c.tn}, {"ignored", c.ignored}, {"out_of_range", c.out_of_range}};
}

}  // namespace

const char* gradeName(ObjectGrade g) {
  return g == ObjectGrade::kDetected  ? "detected"
         : g == ObjectGrade::kPartial ? "partial"
                                      : "missed";
}

GradeCounts EvalReport::gradeCounts() const {
  GradeCounts c;
  if (objects)
    for (const auto& o : *objects) {
      if (!o.scored()) continue;
      const auto g = o.grade();
      c.detected += g == ObjectGrade::kDetected;
      c.partial += g == ObjectGrade::kPartial;
      c.missed += g == ObjectGrade::kMissed;
    }
  return c;
}

ResultInput ResultInput::fromPath(const std::string& result,
                                  const std::optional<std::string>& labels_dir) {
  ResultInput in;
  std::error_code ec;
  if (fs::is_directory(result, ec)) {
    const fs::path d(result);
    if (!io::isCleanmapRun(result))
      throw Error(
          result,
          "has no cleanmap report.json: not a finished cleanmap run (interrupted, or another "
          "tool's folder: give its map file as RESULT and its labels with --labels)");
    if (fs::is_directory(d / "labels")) in.labels_dir = (d / "labels").string();
    for (const char* name : {"static_map_full.ply", "static_map_full.pcd"})
      if (fs::is_regular_file(d / name)) {
        in.map_path = (d / name).string();
        break;
      }
    if (fs::is_regular_file(d / "report.json")) in.run_report = (d / "report.json").string();
    if (fs::is_regular_file(d / "params.ini")) {
      PipelineParams p;
      io::loadParams((d / "params.ini").string(), p);
      in.crop_tau = p.filter.crop_tau;
    }
  } else if (fs::is_regular_file(result, ec)) {
    in.map_path = result;
  } else {
    throw Error(result, "no such result file or folder");
  }
  if (labels_dir) {
    io::requireDirectory(*labels_dir);
    in.labels_dir = *labels_dir;
  }
  if (!in.labels_dir && !in.map_path)
    throw Error(
        result,
        "nothing to score: no labels/ folder and no static_map_full.ply (or give --labels)");
  return in;
}

bool inMapGroundTruth(const Eigen::Vector3f& p, double map_range, double crop_tau) {
  if (map_range > 0 && double(p.x()) * p.x() + double(p.y()) * p.y() > map_range * map_range)
    return false;
  return !(crop_tau > 0 && (p.cwiseAbs().array() > float(crop_tau)).any());
}

EvalReport evaluate(const std::string& gt_dir, const ResultInput& result, const EvalOptions& opt) {
  io::KittiReadOptions ro;
  ro.scan.allow_empty = true;
  ro.load_images = opt.camera_fov;  // the camera (calibration, image size); no image is decoded
  const auto seq = io::KittiSequence::open(gt_dir, ro);
  if (!seq.hasLabels()) throw Error(gt_dir, "no labels/ folder: not a labelled sequence");
  const auto camera = seq.camera();
  if (opt.camera_fov && !camera)
    throw Error(gt_dir,
                "--camera-fov needs the sequence's camera (image_2/ and calib.txt with P2 "
                "and Tr, or KITTI raw's calibration)");
  if (seq.size() == 0) throw Error(gt_dir, "no scans");
  const std::size_t first = static_cast<std::size_t>(std::max(0L, opt.first));
  const std::size_t last =
      opt.last < 0 ? seq.size() - 1 : std::min<std::size_t>(seq.size() - 1, std::size_t(opt.last));
  if (first > last)
    throw Error(gt_dir, "the scan range is empty (the sequence has " + std::to_string(seq.size()) +
                            " scans)");

  EvalReport rep;
  rep.gt_dir = gt_dir;
  rep.sequence = fs::path(gt_dir).lexically_normal().filename().string();
  if (rep.sequence.empty())
    rep.sequence = fs::path(gt_dir).lexically_normal().parent_path().filename().string();
  rep.result = result.map_path ? *result.map_path : result.labels_dir ? *result.labels_dir : "";
  rep.map_range = opt.map_range;
  if (opt.crop_tau)
    rep.crop_tau = *opt.crop_tau;
  else if (opt.run_crop) {
    if (!result.crop_tau)
      throw Error(rep.result, "has no params.ini: the run's crop is unknown (give --crop TAU)");
    rep.crop_tau = *result.crop_tau;
  }
  rep.radius = opt.radius;
  rep.camera_fov = opt.camera_fov;
  if (result.run_report) rep.runtime = readRunReport(*result.run_report);

  std::vector<io::GtObject> objects;
  if (result.labels_dir) {
    rep.mos = MosCounts{};
    if (const auto op = seq.objectsPath()) {
      objects = io::readObjects(*op);
      rep.objects.emplace();
      for (const auto& o : objects)
        if (o.movingAnywhere()) rep.objects->push_back({o.id, o.name, o.cls});
    }
  }
  std::optional<RadiusIndex> map;
  std::optional<MapScorer> scorer;
  std::vector<Eigen::Vector3f> leftovers;
  if (result.map_path) {
    if (!seq.hasPoses())
      throw Error(gt_dir, "scoring a map needs the sequence's poses (poses.txt)");
    const auto cloud = io::readCloud(*result.map_path);
    std::vector<Eigen::Vector3f> pts;
    pts.reserve(cloud.size());
    for (const auto& p : cloud) pts.push_back(p.xyz());
    map.emplace(std::move(pts), opt.radius);
    scorer.emplace(*map);
  }
  if (!opt.pictures_dir.empty()) {
    std::error_code ec;
    fs::create_directories(opt.pictures_dir, ec);
    if (ec) throw Error(opt.pictures_dir, "cannot create the pictures folder: " + ec.message());
  }

  for (std::size_t i = first; i <= last; ++i) {
    const Scan scan = seq.loadScan(i);
    const Labels all_truth = seq.loadLabels(i, scan.original_size);
    // The per-point and object measures' truth: outside the camera's view, ignored.
    Labels fov_truth;
    if (opt.camera_fov) {
      fov_truth.assign(all_truth.size(), 0);
      for (std::size_t j = 0; j < scan.size(); ++j)
        if (camera->project(scan.points[j].xyz().cast<double>()))
          fov_truth[scan.originalIndex(j)] = all_truth[scan.originalIndex(j)];
    }
    const Labels& truth = opt.camera_fov ? fov_truth : all_truth;
    Labels pred;
    if (result.labels_dir) {
      const std::string path = *result.labels_dir + "/" + seq.stems()[i] + ".label";
      pred = io::readLabels(path, scan.original_size);
      const MosCounts c = compareLabels(pred, truth, path);
      *rep.mos += c;
      rep.per_scan.emplace_back(seq.stems()[i], c);
    }
    // Object level (paper Table II): moving ground-truth points inside the object's box.
    if (rep.objects) {
      std::vector<std::pair<std::size_t, const io::ObjectState*>> boxes;  // index in rep.objects
      for (std::size_t k = 0; k < rep.objects->size(); ++k) {
        const auto& o = *std::find_if(objects.begin(), objects.end(), [&](const io::GtObject& g) {
          return g.id == (*rep.objects)[k].id;
        });
        const auto it = o.frames.find(i);
        if (it != o.frames.end() && it->second.motion == io::Motion::kMoving)
          boxes.emplace_back(k, &it->second);
      }
      if (!boxes.empty())
        for (std::size_t j = 0; j < scan.size(); ++j) {
          const uint32_t oi = scan.originalIndex(j);
          if (gtClass(truth[oi]) != GtClass::kMoving || pred[oi] == 0) continue;
          const Eigen::Vector3d p = scan.points[j].xyz().cast<double>();
          for (const auto& [k, box] : boxes)
            if (box->contains(p, kObjectMargin)) {
              auto& r = (*rep.objects)[k];
              ++r.moving_points;
              if (gtClass(pred[oi]) == GtClass::kMoving) ++r.labelled_moving;
              break;
            }
        }
    }
    // DynamicMap scores: every labelled point within the map range (and crop), world frame.
    if (scorer) {
      const Eigen::Isometry3f pose = seq.poses()[i].cast<float>();
      for (std::size_t j = 0; j < scan.size(); ++j) {
        // The points ahead, hinted (RadiusIndex::prefetchAhead; some will be skipped below).
        scorer->prefetchAhead(j, scan.size(), [&](std::size_t k) -> Eigen::Vector3f {
          return pose * scan.points[k].xyz();
        });
        const GtClass t = gtClass(all_truth[scan.originalIndex(j)]);
        if (t == GtClass::kIgnore) continue;
        const Eigen::Vector3f p = scan.points[j].xyz();
        if (!inMapGroundTruth(p, rep.map_range, rep.crop_tau)) continue;
        const Eigen::Vector3f w = pose * p;
        const uint64_t before = scorer->score().moving_removed;
        scorer->add(w, t == GtClass::kMoving);
        if (t == GtClass::kMoving && scorer->score().moving_removed == before &&
            leftovers.size() < kMaxLeftovers)
          leftovers.push_back(w);
      }
    }
    if (!opt.pictures_dir.empty() && result.labels_dir) {
      std::vector<PointXYZI> pts = scan.points;
      Labels p(scan.size()), t(scan.size());
      for (std::size_t j = 0; j < scan.size(); ++j) {
        p[j] = pred[scan.originalIndex(j)];
        t[j] = truth[scan.originalIndex(j)];
      }
      const auto& c = rep.per_scan.back().second;
      char title[160];
      std::snprintf(title, sizeof title, "%s scan %s  P %.2f R %.2f IoU %.2f", rep.sequence.c_str(),
                    seq.stems()[i].c_str(), c.precision(), c.recall(), c.iou());
      const std::string name = "bev_" + seq.stems()[i] + ".png";
      writePng(opt.pictures_dir + "/" + name, birdsEyeView(pts, p, t,
                                                           rep.crop_tau > 0    ? rep.crop_tau
                                                           : rep.map_range > 0 ? rep.map_range
                                                                               : 50.0,
                                                           title));
      rep.pictures.push_back(name);
    }
    ++rep.scans;
  }
  if (scorer) {
    rep.map = scorer->score();
    if (!opt.pictures_dir.empty()) {
      char title[160];
      std::snprintf(title, sizeof title, "%s clean map (%zu points)  SA %.3f DA %.3f",
                    rep.sequence.c_str(), map->size(), rep.map->sa(), rep.map->da());
      writePng(opt.pictures_dir + "/map_overview.png",
               mapOverview(map->points(), leftovers, title));
      rep.pictures.push_back("map_overview.png");
    }
  }
  return rep;
}

std::string toJson(const EvalReport& r) {
  nlohmann::json j;
  j["sequence"] = r.sequence;
  j["ground_truth"] = r.gt_dir;
  j["result"] = r.result;
  j["scans"] = r.scans;
  if (r.mos) {
    j["scored_points"] = r.camera_fov ? "camera_fov" : "all";
    j["precision"] = r.mos->precision();
    j["recall"] = r.mos->recall();
    j["iou"] = r.mos->iou();
    j["flagged_rate"] = r.mos->flaggedRate();
    j["counts"] = countsJson(*r.mos);
    nlohmann::json per = nlohmann::json::object();
    for (const auto& [stem, c] : r.per_scan)
      per[stem] = {{"precision", c.precision()},
                   {"recall", c.recall()},
                   {"iou", c.iou()},
                   {"counts", countsJson(c)}};
    j["per_scan"] = per;
  }
  if (r.objects) {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& o : *r.objects)
      if (o.scored())
        list.push_back({{"id", o.id},
                        {"name", o.name},
                        {"class", o.cls},
                        {"moving_points", o.moving_points},
                        {"labelled_moving", o.labelled_moving},
                        {"fraction", o.fraction()},
                        {"grade", gradeName(o.grade())}});
    const GradeCounts g = r.gradeCounts();
    j["objects"] = {
        {"detected", g.detected}, {"partial", g.partial}, {"missed", g.missed}, {"list", list}};
  }
  if (r.map) {
    j["SA"] = r.map->sa();
    j["DA"] = r.map->da();
    j["AA"] = r.map->aa();
    j["HA"] = r.map->ha();
    j["map_counts"] = {{"static_total", r.map->static_total},
                       {"static_kept", r.map->static_kept},
                       {"moving_total", r.map->moving_total},
                       {"moving_removed", r.map->moving_removed}};
    j["radius_m"] = r.radius;
    j["map_range_m"] = r.map_range;
    j["crop_m"] = r.crop_tau;
  }
  if (r.runtime) {
    nlohmann::json st = nlohmann::json::object();
    for (const auto& s : r.runtime->stages)
      st[s.stage] = {{"median_ms", s.median_ms}, {"p95_ms", s.p95_ms}};
    j["runtime"] = {{"per_scan", st},
                    {"threads", r.runtime->threads},
                    {"peak_rss_mib", r.runtime->peak_rss_mib},
                    {"wall_s", r.runtime->wall_s},
                    {"scans", r.runtime->scans}};
  }
  j["pictures"] = r.pictures;
  return j.dump(1);
}

void writeReport(const std::string& dir, const EvalReport& r) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw Error(dir, "cannot create the report folder: " + ec.message());
  io::writeFileAtomic(dir + "/report.json", [&](std::ostream& os) { os << toJson(r) << '\n'; });
  io::writeFileAtomic(dir + "/report.md", [&](std::ostream& os) {
    char b[512];
    os << "# cleanmap evaluation: " << r.sequence << "\n\nGround truth `" << r.gt_dir
       << "`, result `" << r.result << "`, " << r.scans << " scans. Measures: DESIGN §5.\n";
    if (r.mos) {
      const auto& c = *r.mos;
      std::snprintf(b, sizeof b,
                    "\n## Per-point moving-object segmentation (paper Table I%s)\n"
                    "| precision | recall | IoU | TP | FP | FN | TN | flagged "
                    "|\n|---|---|---|---|---|---|---|---|\n"
                    "| %.3f | %.3f | %.3f | %llu | %llu | %llu | %llu | %.2f %% |\n",
                    r.camera_fov ? "; points in the camera's view only" : "", c.precision(),
                    c.recall(), c.iou(), (unsigned long long)c.tp, (unsigned long long)c.fp,
                    (unsigned long long)c.fn, (unsigned long long)c.tn, 100.0 * c.flaggedRate());
      os << b;
    }
    if (r.objects) {
      os << "\n## Objects (paper Table II: detected f >= 0.9, partially 0.1 <= f < 0.9"
         << (r.camera_fov ? "; points in the camera's view only" : "")
         << ")\n"
            "| id | class | moving points | labelled moving | f | grade "
            "|\n|---|---|---|---|---|---|\n";
      for (const auto& o : *r.objects) {
        if (!o.scored()) continue;
        std::snprintf(b, sizeof b, "| %d | %s | %llu | %llu | %.3f | %s |\n", o.id, o.cls.c_str(),
                      (unsigned long long)o.moving_points, (unsigned long long)o.labelled_moving,
                      o.fraction(), gradeName(o.grade()));
        os << b;
      }
      const GradeCounts g = r.gradeCounts();
      os << "\nDetected " << g.detected << ", partially detected " << g.partial << ", missed "
         << g.missed << ".\n";
    }
    if (r.map) {
      const auto& m = *r.map;
      char crop[64] = "";
      if (r.crop_tau > 0) std::snprintf(crop, sizeof crop, ", crop %.0f m", r.crop_tau);
      std::snprintf(
          b, sizeof b,
          "\n## Clean map (DynamicMap benchmark; kept = a map point within %.2f m; ground truth "
          "within %.0f m horizontally%s)\n"
          "| SA | DA | AA | HA | static kept / total | moving removed / total "
          "|\n|---|---|---|---|---|---|\n"
          "| %.4f | %.4f | %.4f | %.4f | %llu / %llu | %llu / %llu |\n",
          r.radius, r.map_range, crop, m.sa(), m.da(), m.aa(), m.ha(),
          (unsigned long long)m.static_kept, (unsigned long long)m.static_total,
          (unsigned long long)m.moving_removed, (unsigned long long)m.moving_total);
      os << b;
    }
    if (r.runtime) {
      std::snprintf(
          b, sizeof b,
          "\n## Runtime (from the run report: %d threads, peak RSS %.0f MiB, wall %.1f s)\n"
          "| stage | median ms/scan | p95 ms/scan |\n|---|---|---|\n",
          r.runtime->threads, r.runtime->peak_rss_mib, r.runtime->wall_s);
      os << b;
      for (const auto& s : r.runtime->stages) {
        std::snprintf(b, sizeof b, "| %s | %.1f | %.1f |\n", s.stage.c_str(), s.median_ms,
                      s.p95_ms);
        os << b;
      }
    }
    if (!r.pictures.empty()) {
      os << "\n## Pictures\nBird's-eye views: TP red, FP orange, FN blue, static grey, not scored "
            "dark.\n\n";
      for (const auto& p : r.pictures) os << "![" << p << "](" << p << ")\n";
    }
  });
}

}  // namespace cleanmap::eval
