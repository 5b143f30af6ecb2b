#!/usr/bin/env bash
# Regenerates the README's pictures in docs/ with render_scene (each is the
# tool's own preview.png: left | right | GT disparity | acupoints overlaid).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$root/scripts/setup.sh" --no-install
tool="$root/_build/devel/lib/massage_cell/render_scene"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
small="--width 320 --height 240 --fx 250"
"$tool" --preset back $small --out "$work/mean"
cp "$work/mean/preview.png" "$root/docs/back_mean_subject.png"
"$tool" --preset back $small --subject 21 --light top_left --out "$work/s21"
cp "$work/s21/preview.png" "$root/docs/back_subject21_top_left.png"
"$tool" --preset back $small --subject 5 --light top_right --shift 0.14 --raw --out "$work/s5"
cp "$work/s5/preview.png" "$root/docs/back_subject5_raw_shift14.png"
# CECT on a subject lying turned by 12 degrees: contour, the model's midline in
# the body's frame, placed acupoints coloured by CECT's error, anatomical ones.
"$root/_build/devel/lib/massage_cell/cect_eval" --experiments ideal --subjects 1 --random-points 0 --yaw 12 \
  --pictures "$work/cect" > /dev/null
cp "$work/cect/ideal_s01.png" "$root/docs/cect_subject1_turned12.png"
# The realistic cell: arms touching the trunk cut at their creases, C7 at the
# neck's base (cect_eval --experiments real, condition arms_touching, subject 2).
"$root/_build/devel/lib/massage_cell/cect_eval" --experiments real --condition-subjects 2 --random-points 0 \
  --pictures "$work/real" > /dev/null
cp "$work/real/arms_touching_s02.png" "$root/docs/cect_real_arms_touching.png"
"$tool" --preset boxes $small --out "$work/boxes"
cp "$work/boxes/left.png" "$root/docs/boxes_left.png"
# Dense stereo on Middlebury Teddy (third-party data, read from ../shared; the
# pictures are skipped when it is absent): disparity | errors > 1 px in nonocc
# (| FFD's fattening mask).
eval_tool="$root/_build/devel/lib/massage_cell/stereo_eval"
if "$eval_tool" --scenes teddy --methods hbds --pictures "$work/pics" > /dev/null &&
   "$eval_tool" --scenes teddy --methods hbds --refine ffd-mdc --pictures "$work/pics" > /dev/null; then
  cp "$work/pics/teddy_hbds.png" "$root/docs/teddy_hbds.png"
  cp "$work/pics/teddy_hbds+ffd-mdc.png" "$root/docs/teddy_hbds_ffd_mdc.png"
else
  echo "make_doc_pictures: Middlebury data not found: the stereo pictures were not redone" >&2
fi
ls -la "$root/docs"
