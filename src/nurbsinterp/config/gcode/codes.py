"""The codes and words of RS274/NGC as this reader takes them: what moves, what is a mode, what is refused."""
from __future__ import annotations

import math

MM_PER_INCH = 25.4
#: LinuxCNC's arc tolerances, which this reader accepts exactly as rs274 does (checked in tests/test_rs274.py).
#: I J K: the radii to start and end may differ by ARC_TOL (0.01·2·√2 in the program's units) when the
#: difference is also within ARC_REL_TOL of the radius, and never by more than 100·ARC_TOL.  Such an
#: arc LinuxCNC runs as a spiral; here its centre is moved onto the chord's perpendicular bisector so
#: that it is one circle through both ends when that moves it by no more than the same allowance;
#: otherwise (a tiny chord: the centre would move far and turn the arc's ends) it is read as
#: LinuxCNC's spiral itself (arcs._spiral), never refused.  R: |R| may fall short of half the chord
#: by R_TOL (0.00005 in, in either unit system).
ARC_TOL = 0.01 * 2 * math.sqrt(2)
ARC_REL_TOL = 0.001
R_TOL_MM = 0.00005 * 25.4
DEFAULT_ORDER_G6 = 4
MAX_TURNS = 10_000

# plane -> (first axis, second axis, normal axis) as indices of X Y Z; a ccw arc turns from the
# first axis towards the second, about the normal (G18: Z towards X, about +Y)
PLANES = {170: (0, 1, 2), 180: (2, 0, 1), 190: (1, 2, 0)}
PLANE_NAMES = {170: "G17 (XY)", 180: "G18 (ZX)", 190: "G19 (YZ)"}
AXIS_LETTERS = "XYZ"
OFFSET_LETTERS = "IJK"

MOTION = {0, 10, 20, 30, 52, 53, 62}
#: group 0, the non-modal codes: one a line; those that take axis words exclude a motion's axis words
NON_MODAL = {40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923}
AXIS_CODES = {280, 300, 520, 920}  # non-modal codes whose X Y Z are theirs, not a motion's
HOMES = {280: 5161, 300: 5181}  # G28/G30 -> the first of the parameters holding their stored position
#: modal groups: one code of each at most on a line (as rs274 checks)
GROUPS = ({200, 210}, {900, 910}, {901, 911}, {170, 180, 190}, {930, 940, 950}, {610, 611, 640},
          {540, 550, 560, 570, 580, 590, 591, 592, 593}, {400, 410, 420, 411, 421}, {430, 431, 490}, {980, 990},
          NON_MODAL - {530})  # G53 goes with a motion's G0/G1 (checked where it is carried out)
MODAL = {200, 210, 900, 910, 901, 911, 170, 180, 190, 940, 610, 611, 640} | NON_MODAL - {100}
#: path-control modes (LinuxCNC's SET_MOTION_CONTROL_MODE) -> config.path.BlockMode.control
CONTROL = {610: "exact_path", 611: "exact_stop", 640: "blend"}
#: G-codes that do not move the tool: accepted, listed in the notes
IGNORED_G = {400: "cutter compensation off", 430: "tool length offset",
             431: "dynamic tool length offset", 490: "tool length offset off", 540: "work offset",
             550: "work offset", 560: "work offset", 570: "work offset", 580: "work offset", 590: "work offset",
             591: "work offset", 592: "work offset", 593: "work offset", 800: "cancel canned cycle",
             960: "constant surface speed", 970: "spindle RPM mode", 980: "canned cycle return level",
             990: "canned cycle return level"}
#: G-codes that move the tool, or change coordinates, in ways this reader does not model
REFUSED_G = {100: "G10 (set offsets and tool data)", 410: "G41 (cutter compensation)",
             411: "G41.1 (cutter compensation)", 420: "G42 (cutter compensation)",
             421: "G42.1 (cutter compensation)", 930: "G93 (inverse-time feed)", 950: "G95 (feed per revolution)",
             50: "G5 (cubic spline)", 51: "G5.1 (quadratic spline)", 70: "G7 (lathe diameter mode)",
             80: "G8 (lathe radius mode)", 330: "G33 (spindle-synchronised motion)", 331: "G33.1 (rigid tapping)",
             381: "G38.x (probing)", 382: "G38.x (probing)", 383: "G38.x (probing)", 384: "G38.x (probing)",
             385: "G38.x (probing)", 730: "G73 (canned cycle)", 740: "G74 (canned cycle)",
             760: "G76 (threading cycle)", 810: "G81 (canned cycle)", 820: "G82 (canned cycle)",
             830: "G83 (canned cycle)", 840: "G84 (canned cycle)", 850: "G85 (canned cycle)",
             860: "G86 (canned cycle)", 870: "G87 (canned cycle)", 880: "G88 (canned cycle)",
             890: "G89 (canned cycle)", 171: "G17.1 (UV plane)", 181: "G18.1 (WU plane)",
             191: "G19.1 (VW plane)", 700: "G70", 710: "G71", 720: "G72"}
ENDS_M = {2, 30}
#: M-codes after which LinuxCNC brings motion to rest (it waits on them: no look-ahead through them)
STOP_M = {0: "M0 (program stop)", 1: "M1 (optional stop)", 6: "M6 (tool change)", 60: "M60 (pallet change)",
          66: "M66 (wait on an input)"}
STOP_M.update({m: f"M{m} (a user M-code: LinuxCNC runs it between moves)" for m in range(100, 200)})
#: carried out before the line's motion (LinuxCNC's convert_m comes before convert_g); M0 M1 M60 after it
STOP_BEFORE_MOTION = {6, 66} | set(range(100, 200))
#: M-codes that change the modes in ways this reader does not follow
REFUSED_M = {70: "M70 (save the modal state)", 71: "M71 (invalidate the saved modal state)",
             72: "M72 (restore the modal state)", 73: "M73 (save the modal state, restored at the subroutine's end)"}
MAX_M = 199  # LinuxCNC's M-codes end there: a larger one is an error
#: LinuxCNC's order for a line's modes (interp_convert.cc convert_g): plane, units, path control, distance modes
MODE_ORDER = {170: 0, 180: 0, 190: 0, 200: 1, 210: 1, 610: 2, 611: 2, 640: 2, 900: 3, 910: 3, 901: 4, 911: 4}
IGNORED_WORDS = {"S": "spindle speed", "T": "tool", "H": "tool length offset", "D": "tool radius"}
KNOWN_WORDS = set("GMXYZIJKRPQLFNE") | set(IGNORED_WORDS)  # E: M66's analog input
OTHER_AXES = set("ABCUVW")


def gname(code: int) -> str:
    """G-code name from its tenths: 52 -> 'G5.2', 200 -> 'G20'."""
    whole, tenth = divmod(code, 10)
    return f"G{whole}" if tenth == 0 else f"G{whole}.{tenth}"
