#!/usr/bin/env bash
# Regenerate the example recordings of recordings/README.md (run from the repository root):
#   bash recordings/make_examples.sh
set -euo pipefail
cd "$(dirname "$0")/.."
VIZ3D=".venv/bin/viz3d"
$VIZ3D run scenes/impact_clamped_bar.toml --record recordings/impact_clamped_bar.rrd --out out/impact_clamped_bar.npz
$VIZ3D run scenes/impact_bronze_ball.toml --record recordings/impact_bronze_ball.rrd --out out/impact_bronze_ball.npz
$VIZ3D run scenes/anchor_hoist.toml --record recordings/anchor_hoist.rrd --out out/anchor_hoist.npz   # ~20 s (ALI3-P, compiled kernel cached)
