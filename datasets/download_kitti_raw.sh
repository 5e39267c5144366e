#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Downloads the KITTI raw drives used by the paper (2011_09_26 0091, 0095, 0104; synced+rectified)
# and that day's calibration into DEST (default ./kitti_raw), then checks and unpacks them.
# KITTI is CC BY-NC-SA 3.0: cite Geiger et al., IJRR 2013.
set -euo pipefail
dest=${1:-kitti_raw}
base=https://s3.eu-central-1.amazonaws.com/avg-kitti/raw_data
files=(2011_09_26_calib.zip
       2011_09_26_drive_0091/2011_09_26_drive_0091_sync.zip
       2011_09_26_drive_0095/2011_09_26_drive_0095_sync.zip
       2011_09_26_drive_0104/2011_09_26_drive_0104_sync.zip)
mkdir -p "$dest" && cd "$dest"
for f in "${files[@]}"; do
  name=$(basename "$f")
  [[ -f $name ]] || { curl -fL --retry 3 -o "$name.part" "$base/$f" && mv "$name.part" "$name"; }
done
# Checksums: recorded on first download in SHA256SUMS (KITTI publishes none); verified after.
if [[ -f SHA256SUMS ]]; then sha256sum -c SHA256SUMS; else sha256sum ./*.zip >SHA256SUMS; fi
for f in ./*.zip; do unzip -qn "$f"; done
echo "KITTI raw drives in $PWD/2011_09_26"
