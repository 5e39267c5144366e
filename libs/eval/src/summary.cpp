// SPDX-License-Identifier: BSD-3-Clause
// One Markdown table over several evaluation reports (doc/BENCHMARK.md, `make benchmark`).
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cleanmap/core/error.h"
#include "cleanmap/eval/evaluate.h"
#include "cleanmap/io/files.h"

namespace cleanmap::eval {

std::string summaryTable(const std::vector<std::string>& json_files) {
  std::ostringstream os;
  os << "| sequence | scans | precision | recall | IoU | objects D / P / M | SA | DA | AA | HA "
        "| median ms/scan | p95 ms/scan |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  MosCounts all;
  MapScore all_map;
  int det = 0, part = 0, miss = 0;
  bool any_mos = false, any_map = false, any_obj = false;
  std::size_t scans = 0;
  char b[512];
  auto fmt = [&](bool have, double v, const char* f) {
    if (!have) return std::string("–");
    std::snprintf(b, sizeof b, f, v);
    return std::string(b);
  };
  for (const auto& path : json_files) {
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(io::readTextFile(path));
      const bool mos = j.contains("counts"), map = j.contains("map_counts"),
                 obj = j.contains("objects");
      MosCounts c;
      if (mos) {
        const auto& k = j.at("counts");
        c.tp = k.at("tp"), c.fp = k.at("fp"), c.fn = k.at("fn"), c.tn = k.at("tn");
        all += c;
        any_mos = true;
      }
      MapScore m;
      if (map) {
        const auto& k = j.at("map_counts");
        m.static_total = k.at("static_total"), m.static_kept = k.at("static_kept");
        m.moving_total = k.at("moving_total"), m.moving_removed = k.at("moving_removed");
        all_map += m;
        any_map = true;
      }
      std::string objs = "–";
      if (obj) {
        const int d = j["objects"].at("detected"), p = j["objects"].at("partial"),
                  x = j["objects"].at("missed");
        det += d, part += p, miss += x;
        objs = std::to_string(d) + " / " + std::to_string(p) + " / " + std::to_string(x);
        any_obj = true;
      }
      const bool rt = j.contains("runtime") && j["runtime"]["per_scan"].contains("total");
      const std::size_t n = j.at("scans");
      scans += n;
      os << "| " << j.at("sequence").get<std::string>() << " | " << n << " | "
         << fmt(mos, c.precision(), "%.3f") << " | " << fmt(mos, c.recall(), "%.3f") << " | "
         << fmt(mos, c.iou(), "%.3f") << " | " << objs << " | " << fmt(map, m.sa(), "%.4f") << " | "
         << fmt(map, m.da(), "%.4f") << " | " << fmt(map, m.aa(), "%.4f") << " | "
         << fmt(map, m.ha(), "%.4f") << " | "
         << fmt(rt, rt ? j["runtime"]["per_scan"]["total"].value("median_ms", 0.0) : 0.0, "%.0f")
         << " | "
         << fmt(rt, rt ? j["runtime"]["per_scan"]["total"].value("p95_ms", 0.0) : 0.0, "%.0f")
         << " |\n";
    } catch (const nlohmann::json::exception& e) {
      throw Error(path, std::string("not an evaluation report: ") + e.what());
    }
  }
  if (json_files.size() > 1) {
    const std::string objs =
        any_obj ? std::to_string(det) + " / " + std::to_string(part) + " / " + std::to_string(miss)
                : "–";
    os << "| **all (summed counts)** | " << scans << " | " << fmt(any_mos, all.precision(), "%.3f")
       << " | " << fmt(any_mos, all.recall(), "%.3f") << " | " << fmt(any_mos, all.iou(), "%.3f")
       << " | " << objs << " | " << fmt(any_map, all_map.sa(), "%.4f") << " | "
       << fmt(any_map, all_map.da(), "%.4f") << " | " << fmt(any_map, all_map.aa(), "%.4f") << " | "
       << fmt(any_map, all_map.ha(), "%.4f") << " | – | – |\n";
  }
  return os.str();
}

}  // namespace cleanmap::eval
