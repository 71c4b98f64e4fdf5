# SPDX-License-Identifier: LGPL-2.1-or-later
"""Tolerances and limits of the certified drop-cutter over trimmed faces (:mod:`.faceset`).

Every module of the drop-cutter takes its constants from here; :mod:`.faceset` re-exports
them all.  :attr:`MAX_CROWDED` is read by :meth:`.faceset.FaceSet._chunk` from
:mod:`.faceset`'s own namespace at each call, so setting it there takes effect.
"""

from __future__ import annotations

import numpy as np

#: Certified accuracy of the ball-centre height (mm).
CERTIFY = 1e-4
#: Queries processed together.
QUERY_CHUNK = 2048
#: On more than one thread (:mod:`.parallel`) a call is cut into at least this many chunks
#: per thread (queries differ in cost: a thread done early takes the next chunk) ...
CHUNKS_PER_THREAD = 2
#: ... of at least this many queries under the numba engine (each chunk has a fixed cost per
#: level and face, and the queries of a chunk share their sub-patches); a call of fewer than
#: two such chunks runs on one thread.
PARALLEL_CHUNK = 512
#: The same under the numpy engine, whose many small array operations hold the GIL: there a
#: call of a few thousand queries gains nothing from a second thread (benchmarks.md).
PARALLEL_CHUNK_NUMPY = 2048
#: Most halvings of a root patch; a pair still open then keeps its upper bound as its gap.
MAX_DEPTH = 48
#: A point this factor of R^2 away (squared) still touches the ball: a ball whose rim just
#: grazes a face edge (distance R to rounding) finds its contact (error below R * 1e-6 mm).
TOUCH = 1.0 + 1e-12
#: Levels after which the best contacts are polished by Newton's method (a better lower bound
#: early prunes more sub-patches).
POLISH_LEVELS = (2, 4, 6, 9)
#: Newton steps per polish.
POLISH_STEPS = 4
#: Local parameters of a patch's corners, in the order of ``_corner_index``.
CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
#: Most open sub-patches per query and face at one level (more: the lowest bounds are dropped
#: and reported in the gap, so a degenerate query cannot take unbounded time).
MAX_OPEN = 128
#: A query crowded (more than MAX_OPEN open sub-patches of a face) at this many levels is
#: given up: its open sub-patches' bounds go to its gap.  A ball in a fillet of its own
#: radius (its maximum tied along the fillet's arc) or grazing a wall's edge with its rim
#: keeps 128 sub-patches open down to MAX_DEPTH without it: 12 000 pairs a query instead of
#: about 50.
MAX_CROWDED = 6
#: Trim segments remembered per straddling sub-patch; with more, all of the face's are tested.
MAX_SEGMENTS = 12
#: Half-widths (fractions of the Bezier patch, largest first) of the boxes around a contact
#: tried by the local certificate (:func:`.faceset_regions.face_regions`).
REGION_SIZES = (0.5, 0.25, 0.125, 0.0625, 0.03125)
#: After the last of POLISH_LEVELS, every this many levels the faces' contacts are polished
#: again and their regions sought anew (a contact found late still gets its certificate).
REGION_EVERY = 3
#: Only a face whose best contact lies within this of the query's best (mm) seeks a region:
#: a lower face's sub-patches are dropped by their bounds alone.
REGION_TIE = 0.01
#: A region's side splits a sub-patch only this far (fraction) from the sub-patch's sides.
CUT_MARGIN = 0.02
#: Sub-patch trim classifications (and vertices) remembered per face (see
#: :class:`.faceset_trims._RowCache`).
CLASSIFY_CACHE = 50_000
#: A sub-patch at least RIM_DEPTH halvings deep whose net's box lies farther than this
#: fraction of R from the query (in xy) is bounded by its material's own distance as well
#: (:func:`.faceset_bezier._material_reach`; shallower ones are rarely kept open by the rim,
#: and the bound costs about as much as the rest of theirs).
RIM_FRACTION = 0.9
RIM_DEPTH = 14
#: Margin (mm) taken off that distance for rounding.
RIM_ROUNDING_MM = 1e-11
#: Sub-patches this shallow also offer the surface point below their control point nearest
#: the query as a lower bound (see :func:`.faceset_bounds.sub_patch_bounds`).
SEED_DEPTH = 3
#: The point probe (:meth:`.faceset.FaceSet.height`): samples per side of each Bezier patch,
#: the nearest of them in xy that start Newton's method, and its most steps.
HEIGHT_GRID = 9
HEIGHT_SEEDS = 4
HEIGHT_STEPS = 60
