#!/bin/sh
# The worked example of docs/place.md: regenerate the path, search, write docs/place_example/.
set -e
cd "$(dirname "$0")/../.."
python protocols/examples/make_milling_path.py
campaign place --robot kr240-2 --path protocols/examples/milling_path.csv \
  --out docs/place_example \
  --x-mm 1200..2000 --y-mm -600..600 --z-mm 0..600 --yaw-deg -30..30 \
  --x-step-mm 200 --y-step-mm 200 --z-step-mm 200 --yaw-step-deg 30 \
  --tool-angle-step-deg 15 --config -1,-1,-1 --objective max "$@"
