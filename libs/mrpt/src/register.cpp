// SPDX-License-Identifier: BSD-3-Clause
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/registerAllClasses.h>

#include "cleanmap/mrpt/rawlog.h"

namespace cleanmap::mrpt {

void registerClasses() {
  ::mrpt::obs::registerAllClasses_mrpt_obs();
  ::mrpt::maps::registerAllClasses_mrpt_maps();
}

}  // namespace cleanmap::mrpt
