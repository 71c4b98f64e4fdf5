# SPDX-License-Identifier: LGPL-2.1-or-later
"""Programs: G-code read into moves, tool tables, and LinuxCNC's rs274 check."""
