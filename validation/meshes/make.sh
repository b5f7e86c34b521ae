#!/bin/sh
# Regenerates the unstructured triangle meshes of the validation report's collapse section (§12)
# with gmsh (`pip install gmsh` gives the command; these were made by gmsh 4.15.2).
set -e
cd "$(dirname "$0")"
for h in 0.16 0.08 0.04; do
    gmsh -2 -format msh41 -setnumber h $h footing.geo -o footing_$h.msh > /dev/null
done
for h in 0.1 0.05 0.025; do
    gmsh -2 -format msh41 -setnumber h $h square.geo -o square_$h.msh > /dev/null
done
for h in 0.1 0.05 0.025; do
    gmsh -2 -format msh41 -setnumber h $h cut.geo -o cut_$h.msh > /dev/null
done
