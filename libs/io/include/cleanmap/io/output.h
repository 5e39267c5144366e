// SPDX-License-Identifier: BSD-3-Clause
// SPEC §4: the output folder of a run — labels per scan, binary PLY maps, poses, report.
#pragma once
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cleanmap/core/metrics.h"
#include "cleanmap/core/params.h"
#include "cleanmap/pipeline/laser_pipeline.h"

namespace cleanmap::io {

class PlyStreamWriter;

/// Writes OUTDIR/labels/<stem>.label, static_map.ply, static_map_full.ply, dynamic.ply,
/// poses.txt, params.ini, report.json and report.md. Every file is written atomically; the maps
/// are streamed, so memory does not grow with the sequence.
class OutputWriter {
 public:
  OutputWriter(const std::string& outdir, const std::string& input, const PipelineParams& params);
  ~OutputWriter();

  /// One decided scan, with its evaluation when ground truth exists.
  void write(const ScanResult& r, const std::optional<MosCounts>& eval);
  /// Closes the maps and writes poses and the report. `wall_s`: whole run, seconds.
  void finish(double wall_s);

  const std::string& dir() const { return dir_; }
  std::size_t scans() const { return stats_.size(); }
  std::optional<MosCounts> evaluation() const { return has_eval_ ? std::optional(eval_) : std::nullopt; }

 private:
  std::string dir_, input_;
  PipelineParams params_;
  std::unique_ptr<PlyStreamWriter> compact_, full_, moving_;
  std::vector<Eigen::Isometry3d> poses_;
  std::vector<ScanStats> stats_;
  std::vector<std::string> stems_;
  std::vector<MosCounts> scan_eval_;
  MosCounts eval_;
  bool has_eval_ = false;
};

/// Peak resident memory of this process, MiB.
double peakRssMiB();

}  // namespace cleanmap::io
