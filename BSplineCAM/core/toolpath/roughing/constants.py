# SPDX-License-Identifier: LGPL-2.1-or-later
"""The roughing's constants: entry angles, the bounds the clearing keeps on the width of cut,
the sizes of its searches (lead-ins, peels, ramps) and of its grid."""

from __future__ import annotations

import math

#: Default angle (degrees) at which helical and ramped entries descend.
RAMP_ANGLE_DEG = 3.0
#: Steepest ramp angle accepted (degrees): steeper is a plunge, which roughing makes only into
#: a closed pocket no helix or zig-zag ramp enters, with an end mill that cuts at its centre.
MAX_RAMP_ANGLE_DEG = 30.0
#: A closed pocket no helix enters is entered by a zig-zag ramp along its longest straight
#: chord (of CHORD_DIRECTIONS tried through its point farthest from the walls) when the
#: chord is at least this many tool diameters long: each sweep then carries the whole bottom
#: of the tool past where it started, so every point under it at a sweep's end has been
#: passed over by the outer cutting edges on the way down (the uncut core at the middle of an
#: end mill that does not cut at its centre never meets a column left standing), and the
#: drop per sweep (chord x tan(ramp angle)) is a ramp's, not a plunge's.
ZIGZAG_MIN_DIAMETERS = 1.0
CHORD_DIRECTIONS = 36
#: A wall piece a front reaches is cut right after it when the material left beside it
#: reaches deeper than this share of the stepover into the tool's disk; thinner slivers wait
#: for the level's last pass along the wall.
WALL_SLIVER = 0.5
#: A ring round a helix that would stop this close (cells) short of a wall goes half way to it.
RING_MARGIN_CELLS = 3
#: A stay-down lead-in may join a pass this many tool diameters along it from its start.
LEAD_IN_DIAMETERS = 3.0
#: A lead-in from the floor already cut (a straight descent in the cleared region, then a
#: feed to a vertex of the pass within LEAD_IN_DIAMETERS) starts within this many tool radii
#: of the pass's start, on a lattice this share of the radius apart, and at most
#: LEAD_IN_TRIES such feeds are measured (:meth:`_Job.cleared_lead_in`).
LEAD_IN_REACH_RADII = 2.5
LEAD_IN_LATTICE = 0.25
LEAD_IN_TRIES = 40
#: At most this many lead-ins whose route is measured (:meth:`_Job.runs_within`) per pass.
LEAD_IN_ROUTES = 8
#: Fronts bent towards the walls (:meth:`_Job.level` with ``layer``): within this many tool
#: radii of a wall a front grows by less, down to a share of the stepover at the wall (one of
#: WALL_LAYER_STEPS; the share rises quadratically with the distance, so that the front
#: bends smoothly), and so comes to the wall at a slant instead of head-on.  A level is cut
#: so only when its plain fronts cut wider than ENGAGEMENT_LIMIT stepovers, and kept only
#: if that cuts narrower (:meth:`_Job.level_best`).
WALL_LAYER_RADII = 2.0
WALL_LAYER_STEPS = (0.8, 0.65)
#: Shares of the stepover by which a level's bent fronts grow when at the full stepover
#: they still cut wider than ENGAGEMENT_LIMIT (:meth:`_Job.level_best`): closer fronts
#: leave thinner wedges where they meet the walls and each other.
STEPOVER_SCALES = (0.9, 0.8, 0.7)
#: A floor ring's front grows by :func:`ring_steps` of the radius it has there
#: (:func:`front_radius`, smoothed by box means reaching FRONT_SMOOTH_RADII tool radii to each
#: side), by at least MIN_FRONT_STEP stepovers.
FRONT_SMOOTH_RADII = 0.5
MIN_FRONT_STEP = 0.25
#: Widest cut accepted (times the stepover; :meth:`_Job.engaged_width`, which counts a grid
#: cell for the cells' own width) before a level's bent fronts are tried: the bound the
#: clearing keeps.
ENGAGEMENT_LIMIT = 1.1
#: The replay marks a descent in pieces each spanning at most this much height (mm), the
#: surface estimate dropping to the piece's highest tip height (:meth:`_Job.replay`).
DESCENT_BAND_MM = 0.05
#: A level's feed moves (outside its entries) still wider than PEEL_OVER stepovers when the
#: level is kept are cut instead by a few feeds each no wider than PEEL_WIDTH stepovers
#: (:meth:`_Job.peel`): at most PEEL_STEPS, to points on a lattice PEEL_LATTICE tool radii
#: apart within R of the move.
PEEL_OVER = 1.0
PEEL_WIDTH = 1.0
PEEL_STEPS = 24
PEEL_LATTICE = 0.25
#: Where a peel is stuck, it tries ways to at most PEEL_APPROACHES points whose feed to the
#: move's end takes what is left within the width (:meth:`_Job.peel_approach`).
PEEL_APPROACHES = 4
#: A peel's steps may stand out of the region as far as the move it replaces does (a
#: contour's corner some hundredths of a mm out; 0.064 mm at most on the case study), at
#: most PEEL_SLACK_MM.
PEEL_SLACK_MM = 0.1
#: A level move after an entry's descent whose end and midpoint lie this close (mm) to the
#: descent's track is part of the entry in a level's replay (the job simulation's
#: ENTRY_REACH_MM).
ENTRY_TRACK_MM = 0.02
#: A ramp backwards into an open pass starts where the material's top lies at most
#: BACK_RAMP_TOL_MM above the ramp's top, found in at most BACK_RAMP_ROUNDS rounds
#: (:meth:`_Job.back_ramp`).
BACK_RAMP_ROUNDS = 8
BACK_RAMP_TOL_MM = 1e-4
#: Gap (mm) kept above the material by rapids that travel below the clearance height.
TRAVEL_GAP_MM = 1.0
#: Chord error of the helices (mm).
HELIX_CHORD_MM = 0.01
#: Largest number of grid cells; a finer cell is coarsened with a note.
MAX_CELLS = 4_000_000
#: Largest gap (mm) between a ring round a helix and the chords it is cut in: a chord of a
#: ring sweeps across more of the material than the tangent move ring_step assumes (1.8 mm
#: chords on a 6.5 mm ring cut 4.7 mm wide at a 4 mm stepover; 0.7 mm chords 4.3 mm).
RING_CHORD_MM = 0.02
#: Rounds of corner cutting that smooth a floor ring's fronts (:meth:`_Job.smoothed`).
SMOOTH_ROUNDS = 3
#: Largest distance (cells) by which a pass may run inside its contour where that straightens
#: out the contour's stairs (:meth:`_Job.inner_chords`).
STAIR_CELLS = 1.0
#: Slope below which an area counts as flat (degrees) for the extra levels.
FLAT_SLOPE_DEG = 1.0
#: Flat areas smaller than this many tool areas get no level of their own.
FLAT_TOOL_AREAS = 2.0
#: Height (mm) of the material under a bull-nose's or ball's corner, left by a pass beside,
#: from which a move counts it in its width of cut (:meth:`_Job.engaged_widths`): the job
#: simulation's engagement threshold at its 0.1 mm cells.
FILLET_MM = 0.01
_EPS = 1e-6
#: Half a cell's diagonal, in cells.
CELL_HALF_DIAGONAL = 0.5 * math.sqrt(2.0)
#: Footprint growth against the grid (cells): a contour point lies on a cell edge, up to one
#: cell from the allowed centre it was interpolated from, and simplification moves it by a
#: quarter cell more; T at a centre then bounds the true T within 1.5 cells of it.
GRID_GROWTH_CELLS = 1.5
