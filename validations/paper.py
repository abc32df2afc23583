"""The seed paper's claims and r_e grid, shared by the four cases (docs/method.md section 8).

Xu, T. and Jin, Y.-C. (2016), *Improvements for accuracy and stability in a weakly-compressible
particle method*, Computers & Fluids 137:1-14.  The claims come from its abstract and
introduction; each case tests those its runs can decide (``Case.claims``), with the rule written
next to the verdict.  A claim tested by two cases (C8) gets a verdict from each.
"""

from __future__ import annotations

from mpsbench.cases import Claim

# The radii of the paper's diffusion and Couette grids (docs/method.md 6a, 6b).
RE_RATIOS = (2.1, 2.5, 3.1, 3.5, 4.0)

SOURCE = "Xu & Jin (2016), abstract and introduction"

C1 = Claim("C1", "LM3 gives accurate results in the 2-D diffusion test.", SOURCE)
C2 = Claim("C2", "LM3 is more accurate than LM1 and LM2 in Couette flow, across r_e and WF.",
           SOURCE)
C3 = Claim("C3", "The weighting function plays an insignificant role in LM3's accuracy "
           "(Couette flow).", SOURCE)
C4 = Claim("C4", "The stabilization greatly reduces pressure noise and unphysical pressure "
           "fluctuations (the water jet; the hydrostatic column tests it too).", SOURCE)
C5 = Claim("C5", "The stabilization keeps the number density near n0 and minimises particle "
           "penetration (water jet).", SOURCE)
C6 = Claim("C6", "IWC-MPS attains good agreement with the dam-break experiments.", SOURCE)
C7 = Claim("C7", "Pressure noise and unphysical fluctuations are greatly eliminated in the dam "
           "break (IWC-MPS against WC-MPS).", SOURCE)
C8 = Claim("C8", "LM2 serves the pressure calculation rather than viscous accuracy.", SOURCE)
C9 = Claim("C9", "LM1 needs a parameter (lambda) and remains inexact.", SOURCE)

# The names the claims use for the Laplacians (docs/method.md section 3).
LM1, LM2, LM3 = "koshizuka-oka", "khayyer-gotoh", "xu-jin"
