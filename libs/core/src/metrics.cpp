// SPDX-License-Identifier: BSD-3-Clause
#include "cleanmap/core/metrics.h"

#include "cleanmap/core/error.h"

namespace cleanmap {

MosCounts& MosCounts::operator+=(const MosCounts& o) {
  tp += o.tp;
  fp += o.fp;
  fn += o.fn;
  tn += o.tn;
  ignored += o.ignored;
  out_of_range += o.out_of_range;
  return *this;
}

MosCounts compareLabels(const Labels& predicted, const Labels& truth, const std::string& what) {
  if (predicted.size() != truth.size())
    throw Error(what, "has " + std::to_string(predicted.size()) + " predicted labels but " +
                          std::to_string(truth.size()) + " ground-truth labels");
  MosCounts c;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const GtClass g = gtClass(truth[i]);
    if (g == GtClass::kIgnore) {
      ++c.ignored;
      continue;
    }
    const uint32_t p = predicted[i] & 0xFFFFu;
    if (p == kUnclassified) {
      ++c.out_of_range;
      continue;
    }
    const bool pm = gtClass(p) == GtClass::kMoving, gm = g == GtClass::kMoving;
    if (pm && gm)
      ++c.tp;
    else if (pm)
      ++c.fp;
    else if (gm)
      ++c.fn;
    else
      ++c.tn;
  }
  return c;
}

}  // namespace cleanmap
