"""The parameters a program reads and sets, scoped as LinuxCNC scopes them.

Numbered parameters ``#1``..``#5601`` (LinuxCNC's ``RS274NGC_MAX_PARAMETERS`` is
5602) are one table for the whole program; an unset one reads 0, as in
LinuxCNC, whose table starts at zeros.  ``#1``..``#30`` are a subroutine's
arguments: a call saves the caller's, sets them to the arguments (0 past the
last one) and the return restores them.  Named parameters ``#<name>`` are local
to the call frame that set them (the main program is frame 0), ``#<_name>`` are
global; reading a named parameter nobody set is an error.  Names are
case-insensitive and spaces inside them are dropped (LinuxCNC removes spaces
and lower-cases a line before reading it).

The machine writes the parameters it keeps up to date (the current position
#5420..#5422, the stored positions #5161.., the G92 offsets #5211..) through
``store[number] = value``; a program may read them but, like LinuxCNC, not
assign to #5021..#5029, #5400..#5413 and #5420..#5428.
"""
from __future__ import annotations

#: LinuxCNC's RS274NGC_MAX_PARAMETERS: the numbered parameters are #1..#5601.
NUMBERED = 5602
#: A subroutine's arguments are #1..#30 (LinuxCNC's INTERP_SUB_PARAMS).
SUB_ARGS = 30
#: Call frames, the main program's included (LinuxCNC's INTERP_SUB_ROUTINE_LEVELS): 9 nested calls at most.
CALL_FRAMES = 10
#: What a program may not assign (LinuxCNC's readonly_parameters: machine position, tool, current position).
READ_ONLY = frozenset(range(5021, 5030)) | frozenset(range(5400, 5414)) | frozenset(range(5420, 5429))
#: Named parameters that read the machine's state (LinuxCNC's predefined ones that this reader can know).
_POSITION = {"_x": 5420, "_y": 5421, "_z": 5422}
POSITION = (5420, 5421, 5422)  # where the tool is, X Y Z


def canonical_name(text: str) -> str:
    """A parameter's name as LinuxCNC keys it: lower case, no spaces or tabs."""
    return "".join(text.split()).lower()


class Parameters:
    """The parameter store: ``store[5420]`` (numbered), ``store["feed"]`` or ``store["_safe_z"]`` (named)."""

    def __init__(self, initial: dict | None = None):
        self.numbered = [0.0] * NUMBERED
        self.globals: dict = {}
        self.frames: list = [{}]  # named locals of each call frame; [0] is the main program's
        self._saved: list = []  # the callers' #1..#30, one list per active call
        self.value = 0.0  # the last subroutine's return value: #<_value>
        self.value_returned = 0.0  # whether it returned one: #<_value_returned>
        # #5420..#5422, where the tool is: asked of the machine when read (every line moves it; few read it)
        self.position = None  # a callable () -> (x, y, z) in the program's units and frame, or None
        for key, value in (initial or {}).items():
            self[int(key) if str(key).isdigit() else key] = float(value)

    # -- reading -------------------------------------------------------------------------------
    def __getitem__(self, key):
        if isinstance(key, int):
            return self.read_numbered(key)
        value = self.named(key)
        if value is None:
            raise KeyError(key)
        return value

    def __contains__(self, key) -> bool:
        if isinstance(key, int):
            return 1 <= key < NUMBERED
        return self.named(key) is not None

    def get(self, key, default=None):
        return self[key] if key in self else default

    def read_numbered(self, index: int) -> float:
        if self.position is not None and POSITION[0] <= index <= POSITION[-1]:
            return float(self.position()[index - POSITION[0]])
        return self.numbered[index]

    def named(self, name: str) -> float | None:
        """The value of ``#<name>`` (name canonical), None if it was never set."""
        if name.startswith("_"):
            value = self.globals.get(name)
            if value is not None:
                return value
            if name in _POSITION:
                return self.read_numbered(_POSITION[name])
            if name == "_value":
                return self.value
            if name == "_value_returned":
                return self.value_returned
            if name == "_call_level":
                return float(len(self.frames) - 1)
            return None
        return self.frames[-1].get(name)

    @staticmethod
    def is_read_only(key) -> bool:
        if isinstance(key, int):
            return key in READ_ONLY
        return key in _POSITION or key in ("_value", "_value_returned", "_call_level")

    # -- writing -------------------------------------------------------------------------------
    def __setitem__(self, key, value) -> None:
        if isinstance(key, int):
            self.numbered[key] = value
        elif key.startswith("_"):
            self.globals[key] = value
        else:
            self.frames[-1][key] = value

    def declare(self, name: str) -> None:
        """Create ``#<name>`` at 0 if it does not exist: LinuxCNC does so when it *reads* an assignment to it,
        so that ``#<a>=5 G1 X#<a>`` (``a`` new) moves to 0 and ``#<n>=[#<n>+1]`` counts from 0."""
        if self.named(name) is None:
            self[name] = 0.0

    # -- call frames ---------------------------------------------------------------------------
    @property
    def depth(self) -> int:
        """Active calls (0 in the main program)."""
        return len(self.frames) - 1

    def enter(self, args) -> None:
        """A call: #1..#30 become the arguments (0 past the last), the caller's are kept; new named locals."""
        self._saved.append(self.numbered[1:SUB_ARGS + 1])
        self.numbered[1:SUB_ARGS + 1] = list(args) + [0.0] * (SUB_ARGS - len(args))
        self.frames.append({})

    def leave(self, value: float | None) -> None:
        """A return (``endsub``/``return`` with an optional value): the caller's #1..#30 and locals again."""
        self.numbered[1:SUB_ARGS + 1] = self._saved.pop()
        self.frames.pop()
        self.value, self.value_returned = (0.0, 0.0) if value is None else (value, 1.0)
