#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Remakes the pictures of doc/MRPT.md: runs cleanmap on a KITTI set and photographs MRPT's
# SceneViewer3D showing the cleaned map and RawLogViewer (with our plugin loaded) showing the
# moving points of a scan of labelled.rawlog, under a virtual X server (Xvfb), no screen needed.
# The clicks in RawLogViewer are at fixed places of its 1280x800 layout (MRPT 2.5.8).
# usage: doc/screenshots.sh [BUILD_DIR] [DATA_DIR]   (defaults: build, ../shared/data)
# Installs xvfb, xauth, xdotool and imagemagick with apt-get when missing (as root).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
data=${2:-${CLEANMAP_DATA_DIR:-$root/../shared/data}}
set_=kitti_highway
out=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$out"' EXIT

need=()
for tool in Xvfb:xvfb xauth:xauth xdotool:xdotool import:imagemagick; do
  command -v "${tool%%:*}" >/dev/null || need+=("${tool#*:}")
done
if ((${#need[@]})); then
  apt-get install -y --no-install-recommends "${need[@]}" >/dev/null
fi
[[ -x $build/apps/cleanmap ]] || { echo "screenshots.sh: build first (make demo)" >&2; exit 1; }
[[ -d $data/$set_ ]] || { echo "screenshots.sh: $data/$set_ missing" >&2; exit 1; }

"$build/apps/cleanmap" "$data/$set_" -o "$out/run" --quiet >/dev/null

display=:$((90 + RANDOM % 9))
Xvfb "$display" -screen 0 1280x800x24 >/dev/null 2>&1 &
sleep 2
DISPLAY=$display SceneViewer3D -l "$build/libs/maps/libcleanmap_maps.so" "$out/run/static_map.3Dscene" >/dev/null 2>&1 &
win=
for _ in $(seq 60); do  # the window appears once the scene is loaded
  win=$(DISPLAY=$display xdotool search --name SceneViewer 2>/dev/null | tail -1 || true)
  [[ -n $win ]] && break
  sleep 0.5
done
[[ -n $win ]] || { echo "screenshots.sh: SceneViewer3D did not open a window" >&2; exit 1; }
sleep 3
# No window manager under Xvfb: place and size every window of the viewer by hand.
for w in $(DISPLAY=$display xdotool search --name SceneViewer); do
  DISPLAY=$display xdotool windowmove "$w" 0 0 windowsize "$w" 1280 800 || true
done
sleep 4
mkdir -p "$root/doc/img"
DISPLAY=$display import -window root "$root/doc/img/sceneviewer_${set_}.png"
echo "screenshots.sh: wrote doc/img/sceneviewer_${set_}.png"
pkill -f "SceneViewer3D -l" || true

# Starts RawLogViewer on a rawlog with our plugin loaded (-l), closes its tip of the day and
# makes its main window 1280x800 (no window manager under Xvfb).
rawlogviewer() {
  DISPLAY=$display RawLogViewer -l "$build/libs/maps/libcleanmap_maps.so" "$1" >/dev/null 2>&1 &
  local tip=
  for _ in $(seq 60); do
    tip=$(DISPLAY=$display xdotool search --name "Tip of the Day" 2>/dev/null | head -1 || true)
    [[ -n $tip ]] && break
    sleep 0.5
  done
  [[ -n $tip ]] || { echo "screenshots.sh: RawLogViewer did not open" >&2; exit 1; }
  sleep 1
  eval "$(DISPLAY=$display xdotool getwindowgeometry --shell "$tip")"
  DISPLAY=$display xdotool mousemove $((X + WIDTH - 54)) $((Y + HEIGHT - 28)) click 1  # "Close"
  sleep 1
  for w in $(DISPLAY=$display xdotool search --name "RawlogViewer - Part"); do
    DISPLAY=$display xdotool windowmove "$w" 0 0 windowsize "$w" 1280 800 || true
  done
  sleep 2
}

# RawLogViewer on labelled.rawlog: scan 4's LIDAR_MOVING cloud.
rawlogviewer "$out/run/labelled.rawlog"
DISPLAY=$display xdotool mousemove 180 360 click 1  # tree entry [14]: scan 4, LIDAR_MOVING
sleep 3
DISPLAY=$display import -window root "$root/doc/img/rawlogviewer_${set_}_moving.png"
echo "screenshots.sh: wrote doc/img/rawlogviewer_${set_}_moving.png"
pkill -f "RawLogViewer -l" || true
sleep 1

# RawLogViewer's "Map from odometry" building our moving-objects layer from an external-storage
# rawlog (cleanmap-kitti2rawlog --external), poses from its CObservationRobotPose entries.
"$build/apps/cleanmap-kitti2rawlog" "$data/$set_" "$out/external.rawlog" --external >/dev/null
rawlogviewer "$out/external.rawlog"
DISPLAY=$display xdotool mousemove 225 60 click 1  # toolbar "Raw-map..."
sleep 3
form=$(DISPLAY=$display xdotool search --name "Creation of" | head -1)
DISPLAY=$display xdotool windowmove "$form" 0 0 windowsize "$form" 1280 800
sleep 1
DISPLAY=$display xdotool mousemove 900 150 click 1 key ctrl+a BackSpace  # the map ini text
for line in "[map]" "cleanmap_moving_count=1" "[map_cleanmap_moving_00_insertOpts]" \
  "use_pose_observations=1"; do
  DISPLAY=$display xdotool type --delay 5 "$line"
  DISPLAY=$display xdotool key Return
done
DISPLAY=$display xdotool mousemove 133 192 click 1  # "Map from odometry"
sleep 20
DISPLAY=$display xdotool mousemove 304 277 click 1  # "Preview map in 3D"
prev=
for _ in $(seq 60); do
  prev=$(DISPLAY=$display xdotool search --name "Raw-map 3D preview" 2>/dev/null | head -1 || true)
  [[ -n $prev ]] && break
  sleep 0.5
done
[[ -n $prev ]] || { echo "screenshots.sh: no Raw-map 3D preview" >&2; exit 1; }
DISPLAY=$display xdotool windowmove "$prev" 0 0 windowsize "$prev" 1280 800
sleep 4
DISPLAY=$display import -window root "$root/doc/img/rawlogviewer_${set_}_rawmap_external.png"
echo "screenshots.sh: wrote doc/img/rawlogviewer_${set_}_rawmap_external.png"
