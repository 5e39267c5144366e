#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Downloads KITTI odometry (Velodyne, calibration, poses) and SemanticKITTI labels into DEST
# (default ./semantickitti), checks and unpacks them into DEST/dataset/sequences/NN/.
# KITTI: CC BY-NC-SA 3.0; SemanticKITTI labels: CC BY-NC-SA 4.0 (Behley et al., ICCV 2019).
set -euo pipefail
dest=${1:-semantickitti}
files=(https://s3.eu-central-1.amazonaws.com/avg-kitti/data_odometry_velodyne.zip
       https://s3.eu-central-1.amazonaws.com/avg-kitti/data_odometry_calib.zip
       https://s3.eu-central-1.amazonaws.com/avg-kitti/data_odometry_poses.zip
       https://www.semantic-kitti.org/assets/data_odometry_labels.zip)
mkdir -p "$dest" && cd "$dest"
for url in "${files[@]}"; do
  name=$(basename "$url")
  [[ -f $name ]] || { curl -fL --retry 3 -o "$name.part" "$url" && mv "$name.part" "$name"; }
done
if [[ -f SHA256SUMS ]]; then sha256sum -c SHA256SUMS; else sha256sum ./*.zip >SHA256SUMS; fi
for f in ./*.zip; do unzip -qn "$f"; done
# poses.txt per sequence (data_odometry_poses puts them in dataset/poses/NN.txt).
for p in dataset/poses/*.txt; do
  n=$(basename "$p" .txt); [[ -d dataset/sequences/$n ]] && cp -n "$p" "dataset/sequences/$n/poses.txt"
done
echo "SemanticKITTI in $PWD/dataset/sequences"
