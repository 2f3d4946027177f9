#!/usr/bin/env bash
# Remakes the estimation + validation pair in data/ with friction-identify generate.
#
# The system is the reference GMS of `generate --model gms`: four elements, Coulomb level 1.5 N,
# a Stribeck peak of 2 N below 1 mm/s, viscous friction 50 N s/m and a frictional lag of about
# 5 ms: presliding hysteresis with nonlocal memory and every sliding effect at once, which is the
# setting of the paper's comparison.  Force noise 0.01 N; a 10 nm encoder.  The validation record
# uses other speeds, another presliding amplitude and another noise seed than the estimation one.
#
# Usage: bash data/make-data.sh [path/to/friction-identify]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
tool="${1:-$here/../build/apps/friction-identify}"

"$tool" generate --model gms --excitation combined --rate 1000 --stroke 0.5e-3 \
  --speeds 5e-4,1e-3,2e-3,5e-3 --presliding-amplitude 20e-6 --cycles 8 \
  --noise 0.01 --resolution 1e-8 --seed 1 \
  --truth "$here/true-model.json" --out "$here/estimation.csv"
"$tool" generate --model gms --excitation combined --rate 1000 --stroke 0.5e-3 \
  --speeds 3e-4,8e-4,1.5e-3,3e-3 --presliding-amplitude 15e-6 --cycles 6 \
  --noise 0.01 --resolution 1e-8 --seed 2 \
  --out "$here/validation.csv"
