"""The glints' sidelobes out of the warm start (`[init] glint_sidelobes`, rfsdf.radar.glint_sidelobes):
on a scene's simulated data (the demo's settings), the default fit from its warm start with the
rule and without it, on the same data and CLEAN image, for each seed. Per run: how many range
peaks the rule drops and how far they lie from the true surface (beyond 2 mm, within 1 mm),
the amplitude-weighted distance of the peaks kept, and the warm start's and the fit's
observed-surface and whole-surface Chamfer-L1 (distances to the surfaces) with each object's
(`fit_variants.py` with these two variants).

Usage: python benchmarks/glint_sidelobes.py [--scene objects] [--seeds 0,1,2] [--device cpu]
       [--out benchmarks/results/glint-sidelobes-SCENE.json]
"""

from __future__ import annotations

from fit_variants import main

VARIANTS = {"glint sidelobes out (the default)": {}, "kept": {"init": {"glint_sidelobes": False}}}

if __name__ == "__main__":
    main(VARIANTS, "glint-sidelobes")
