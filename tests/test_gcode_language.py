"""The NGC language of the G-code reader: expressions, parameters and O-word control flow, as LinuxCNC 2.9.

Expected values are closed forms (SIN[30] = 1/2, 2**10 = 1024, ...) compared to a few ulps, or exact where
the reader does no arithmetic; a random expression is checked against a naive evaluation of the same tree
(LinuxCNC's precedence, left to right) to 1e-12 relative.  LinuxCNC's own interpreter is the reference in
tests/test_rs274_language.py (opt-in).  The sources of the rules: interp_read.cc (read_real_expression,
read_real_value, read_parameter), interp_execute.cc (execute_binary, execute_unary), interp_o_word.cc.
"""
from __future__ import annotations

import math

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from budgets import budgets

from test_gcode import program, refused  # the one writer and one-line-error check of the G-code tests

from nurbsinterp.config.gcode import program as program_module
from nurbsinterp.config.gcode import read_gcode
from nurbsinterp.config.gcode.expr import EQUAL_TOLERANCE, ExprError, read_value
from nurbsinterp.config.gcode.params import Parameters
from nurbsinterp.config.gcode.program import MAX_REPEATED_LINES
from nurbsinterp.errors import SpecError

EPS = 2.0 ** -52
ULPS = 4 * EPS  # a closed form against libm and one conversion to degrees: a few roundings


def ends(tmp_path, text):
    """The end points (x, y, z) of a program's blocks, mm."""
    blocks = read_gcode(str(program(tmp_path, text))).blocks
    return [tuple(float(c) for c in b.end) + (0.0,) * (3 - len(b.end)) for b in blocks]


def xs(tmp_path, text):
    return [e[0] for e in ends(tmp_path, text)]


def value(expression: str, params: Parameters | None = None) -> float:
    """An expression read as a word's value (the line cleaned as the reader cleans it), all of it consumed."""
    text = "".join(expression.split()).upper()
    result, k = read_value(text, 0, params or Parameters())
    assert k == len(text), f"{expression!r} read only to {text[:k]!r}"
    return result


# =========================================================================== 1. expressions, closed forms

OPERATORS = {
    "[1+2]": 3, "[7-10]": -3, "[2*3.5]": 7, "[7/2]": 3.5, "[2**10]": 1024, "[2**-1]": 0.5, "[-8**[1/3]]": None,
    "[7 MOD 3]": 1, "[-7 MOD 3]": 2, "[7 MOD -3]": 1, "[-7 MOD -3]": 2, "[7.5 MOD 2]": 1.5,  # fmod, then +|b|
    "[1 AND 0]": 0, "[2 AND -1]": 1, "[0 OR 0]": 0, "[0 OR 3]": 1, "[1 XOR 1]": 0, "[1 XOR 0]": 1, "[0 XOR 0]": 0,
    "[1 EQ 1]": 1, "[1 EQ 2]": 0, "[1 NE 2]": 1, "[1 NE 1]": 0, "[2 GT 1]": 1, "[1 GT 1]": 0, "[1 LT 2]": 1,
    "[2 LT 1]": 0, "[1 GE 1]": 1, "[0 GE 1]": 0, "[1 LE 1]": 1, "[2 LE 1]": 0,
    # within LinuxCNC's TOLERANCE_EQUAL: EQ and the equal side of GE/LE are fuzzy, LT/GT exact
    "[1 EQ 1.0000005]": 1, "[1 EQ 1.000002]": 0, "[1 NE 1.0000005]": 0, "[1 GE 1.0000005]": 1,
    "[1.0000005 LE 1]": 1, "[1 LT 1.0000005]": 1, "[1.0000005 GT 1]": 1, "[1 LE 0.99]": 0,
}
FUNCTIONS = {
    "ABS[-2.5]": 2.5, "ABS[3]": 3, "ACOS[0.5]": 60, "ACOS[-1]": 180, "ASIN[0.5]": 30, "ASIN[-1]": -90,
    "ATAN[1]/[1]": 45, "ATAN[1]/[-1]": 135, "ATAN[-1]/[-1]": -135, "ATAN[0]/[-1]": 180, "ATAN[1]/[0]": 90,
    "COS[60]": 0.5, "COS[180]": -1, "SIN[30]": 0.5, "SIN[-90]": -1, "TAN[45]": 1, "EXP[1]": math.e,
    "EXP[0]": 1, "LN[1]": 0, "LN[EXP[2]]": 2, "SQRT[16]": 4, "SQRT[2]": math.sqrt(2), "FIX[2.5]": 2,
    "FIX[-2.5]": -3, "FUP[2.1]": 3, "FUP[-2.5]": -2, "FUP[3]": 3, "ROUND[2.5]": 3, "ROUND[-2.5]": -3,
    "ROUND[2.4999]": 2, "ROUND[0.5]": 1, "EXISTS[#<_value>]": 1, "EXISTS[#<nowhere>]": 0, "EXISTS[#5601]": 1,
    "EXISTS[#5602]": 0, "EXISTS[#0]": 0,
}
PRECEDENCE = {
    "[2+3*4]": 14, "[2*3+4]": 10, "[2*3**2]": 18, "[2**3**2]": 64, "[2**3*2]": 16,  # ** left to right too
    "[-2**2]": 4, "[2*-3]": -6, "[1--1]": 2, "[10-2-3]": 5, "[16/4/2]": 2, "[2*6 MOD 5]": 2, "[7 MOD 4*2]": 6,
    "[1+1 EQ 2]": 1, "[1 EQ 1 AND 2 EQ 2]": 1, "[1 OR 0 XOR 1]": 0, "[0 AND 0 OR 1]": 1, "[1+2 GT 2+0.5]": 1,
    "[[1+2]*3]": 9, "-[1+2]": -3, "--1": 1, "+-1": -1, "-SIN[30]": -0.5, "[2*SIN[30]]": 1,
    "[3-2 LT 2-1]": 0, "[1 LT 2 EQ 1]": 1, "[2 + -ABS[-3]]": -1, "[1.5]": 1.5, "[.5+1.]": 1.5,
}


@pytest.mark.parametrize("expression", [e for e in OPERATORS if OPERATORS[e] is not None])
def test_operators(expression):
    assert value(expression) == OPERATORS[expression]


@pytest.mark.parametrize("expression", list(FUNCTIONS))
def test_functions_in_degrees(expression):
    expected = FUNCTIONS[expression]
    assert math.isclose(value(expression), expected, rel_tol=ULPS, abs_tol=ULPS), (value(expression), expected)


@pytest.mark.parametrize("expression", list(PRECEDENCE))
def test_precedence_and_signs(expression):
    assert math.isclose(value(expression), PRECEDENCE[expression], rel_tol=ULPS, abs_tol=0)


def test_the_equal_tolerance_is_linuxcncs():
    assert EQUAL_TOLERANCE == 1e-6  # interp_internal.hh, LinuxCNC 2.9.0 and later


def test_spaces_and_case_inside_expressions(tmp_path):
    assert xs(tmp_path, "g1 f60 x [ 1 + 2 * sin [ 30 ] ]\nG1 X[4 mod 3]Y[2 ** 2]\n") == [2.0, 1.0]


def test_numbered_parameters_direct_and_indirect(tmp_path):
    params = Parameters()
    params[1], params[5], params[7] = 5.0, 7.0, 9.0
    assert value("#1", params) == 5 and value("##1", params) == 7 and value("###1", params) == 9
    assert value("#[2+3]", params) == 7 and value("-#1", params) == -5 and value("#5.00001", params) == 7
    assert value("#4000", params) == 0  # unset: 0, as LinuxCNC's table starts at zeros
    with pytest.raises(ExprError, match="not an integer"):
        value("#1.5", params)


def test_named_parameters_are_case_and_space_insensitive(tmp_path):
    assert ends(tmp_path, "#<Safe Height>=5\nG1 F60 X#<safeheight> Y#<SAFE HEIGHT>\n") == [(5.0, 5.0, 0.0)]


def test_assignments_on_a_line_take_effect_after_it(tmp_path):
    assert xs(tmp_path, "#1=1\n#1=2 #2=#1 G1 F60 X#1\nG1 X[#1*10+#2]\n") == [1.0, 21.0]


def test_a_named_assignment_creates_its_name_as_linuxcnc_reads_it(tmp_path):
    """LinuxCNC adds `#<a>` (at 0) when it reads `#<a>=`: read later on the same line it is 0, not an error."""
    assert xs(tmp_path, "#<a>=5 G1 F60 X#<a>\nG1 X#<a>\n#<n>=[#<n>+1]\nG1 X[#<n>+10]\n") == [5.0, 11.0]
    refused(tmp_path, "G1 F60 X#<b> #<b>=5\n", 1, "X#<b>", "#<b> is read before it is set")


def test_position_and_return_value_parameters(tmp_path):
    params = Parameters()
    params[5420], params[5421], params[5422] = 1.0, 2.0, 3.0  # as the machine keeps them
    assert [value(f"#<_{a}>", params) for a in "xyz"] == [1.0, 2.0, 3.0]
    assert value("#<_value>", params) == 0 and value("#<_value_returned>", params) == 0


# =========================================================================== 2. random expressions

_PREC = {"**": 6, "*": 5, "/": 5, "MOD": 5, "+": 4, "-": 4, "EQ": 3, "NE": 3, "GT": 3, "GE": 3, "LT": 3,
         "LE": 3, "AND": 2, "OR": 2, "XOR": 2}


def _naive(op, a, b):
    """The oracle: each operator from its definition in LinuxCNC's execute_binary, written out plainly."""
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    if op == "/":
        if b == 0:
            raise ZeroDivisionError
        return a / b
    if op == "MOD":
        assume(b != 0)
        r = math.fmod(a, b)
        return r + abs(b) if r < 0 else r
    if op == "**":
        return a ** b  # the generator gives ** a small integer exponent only
    tol = 1e-6
    return float({"EQ": abs(a - b) < tol, "NE": abs(a - b) >= tol, "GT": a > b, "LT": a < b,
                  "GE": abs(a - b) < tol or a >= b, "LE": abs(a - b) < tol or a <= b,
                  "AND": a != 0 and b != 0, "OR": a != 0 or b != 0, "XOR": (a != 0) != (b != 0)}[op])


NUMBERS = st.integers(-9999, 9999).map(lambda n: n / 100)
#: Unary functions whose value is exact (no libm rounding): the oracle computes them bit for bit.
_UNARY = {"ABS": abs, "FIX": lambda x: float(math.floor(x)), "FUP": lambda x: float(math.ceil(x)),
          "ROUND": lambda x: float(math.trunc(x + (0.5 if x >= 0 else -0.5))), "-": lambda x: -x}
TREES = st.recursive(
    NUMBERS,
    lambda inner: st.one_of(
        st.tuples(st.sampled_from([o for o in _PREC if o != "**"]), inner, inner),
        st.tuples(st.just("**"), inner, st.integers(0, 3).map(float)),
        st.tuples(st.sampled_from(sorted(_UNARY)), inner)),
    max_leaves=12)


def _render(tree, brackets) -> str:
    """The tree as NGC text with the brackets precedence needs (left to right), and some it does not."""
    if isinstance(tree, float):
        return f"{tree:.2f}"
    if len(tree) == 2:  # a function, or a sign: it applies to the bracket right after it
        return f"{tree[0]}[{_render(tree[1], brackets)}]"
    op, left, right = tree
    lhs, rhs = _render(left, brackets), _render(right, brackets)
    if isinstance(left, tuple) and len(left) == 3 and (_PREC[left[0]] < _PREC[op] or brackets.draw(st.booleans())):
        lhs = f"[{lhs}]"
    if isinstance(right, tuple) and len(right) == 3 and (_PREC[right[0]] <= _PREC[op] or brackets.draw(st.booleans())):
        rhs = f"[{rhs}]"
    return f"{lhs} {op} {rhs}"


def _evaluate(tree):
    if isinstance(tree, float):
        return tree
    if len(tree) == 2:
        return _UNARY[tree[0]](_evaluate(tree[1]))
    op, left, right = tree
    return _naive(op, _evaluate(left), _evaluate(right))


@budgets(quick=100, full=400)
def test_random_expressions_agree_with_a_naive_evaluation_of_their_tree(budget):
    @settings(max_examples=budget, deadline=None)
    @given(tree=TREES, data=st.data())
    def check(tree, data):
        text = "[" + _render(tree, data) + "]"
        try:
            expected = _evaluate(tree)
        except ZeroDivisionError:
            with pytest.raises(ExprError, match="division by zero"):
                value(text)
            return
        except OverflowError:
            assume(False)
        assume(math.isfinite(expected) and abs(expected) < 1e300)
        got = value(text)
        assert math.isclose(got, expected, rel_tol=1e-12, abs_tol=1e-300), (text, got, expected)

    check()


# =========================================================================== 3. O-words

def test_sub_call_arguments_and_return_value(tmp_path):
    got = ends(tmp_path, """
        G1 F60
        #1=5
        o100 sub
          G1 X#1 Y#2 Z#3
          #1=9
        o100 endsub [#1*2]
        o100 call [1] [2]
        G1 X#1 Y#<_value> Z#<_value_returned>
        o100 call
        o<Named> call [7]
        G1 Y[#<_value>+1] Z#<_value_returned>  (endsub without a value: 0, and none returned)
        M2
        o<named> sub
          G1 X#1
        o<named> endsub
        """)
    assert got == [(1, 2, 0), (5, 18, 1), (0, 0, 0), (7, 0, 0), (7, 1, 0)]


def test_scopes_of_named_parameters(tmp_path):
    """A sub sees globals and its own locals, not its caller's; its locals vanish on return."""
    assert xs(tmp_path, """
        #<_g>=3
        #<local>=4
        o1 sub
          #<local>=[#<_g>*10]
          #<_g>=[#<local>+1]
          G1 F60 X#<local>
        o1 endsub
        o1 call
        G1 X[#<local>+#<_g>]
        """) == [30.0, 35.0]
    refused(tmp_path, "#<a>=1\no1 sub\nG1 F60 X#<a>\no1 endsub\no1 call\n", 3, "#<a>", "before it is set")


def test_numbered_arguments_are_per_call(tmp_path):
    """#1..#30 are saved by a call and restored by its return, through a recursion; #31 is global."""
    assert xs(tmp_path, """
        G1 F60
        o<down> sub
          #31=[#31+1]
          o2 if [#1 GT 0]
            o<down> call [#1-1]
          o2 endif
          G1 X[#1*100+#31]
        o<down> endsub
        o<down> call [3]
        """) == [4.0, 104.0, 204.0, 304.0]


def test_if_elseif_else(tmp_path):
    text = """
        #1={n}
        o1 if [#1 EQ 1]
          G1 F60 X1
        o1 elseif [#1 EQ 2]
          G1 F60 X2
        o1 elseif [#1 EQ 3]
          G1 F60 X3
        o1 else
          G1 F60 X4
        o1 endif
        G1 Y1
        """
    for n, expected in ((1, 1.0), (2, 2.0), (3, 3.0), (7, 4.0)):
        assert ends(tmp_path, text.format(n=n)) == [(expected, 0, 0), (expected, 1, 0)]


def test_a_branch_not_taken_is_not_read(tmp_path):
    assert xs(tmp_path, "o1 if [0]\nG1 X@@ (anything)\n#<x>=[1/0]\no1 endif\nG1 F60 X1\n") == [1.0]


def test_while_do_repeat_break_continue(tmp_path):
    got = ends(tmp_path, """
        G1 F60
        #1=0
        o1 repeat [2.5]  (nearbyint: 2)
          #1=[#1+1]
          G1 X#1
        o1 endrepeat
        o2 do
          #1=[#1+1]
          o3 if [#1 EQ 5]
            o2 continue
          o3 endif
          G1 Y#1
        o2 while [#1 LT 7]
        o4 while [1]
          #1=[#1+1]
          o5 if [#1 GT 9]
            o4 break
          o5 endif
          G1 Z#1
        o4 endwhile
        o6 while [0]
          G1 X99
        o6 endwhile
        o7 repeat [0]
          G1 X99
        o7 endrepeat
        """)
    assert got == [(1, 0, 0), (2, 0, 0), (2, 3, 0), (2, 4, 0), (2, 6, 0), (2, 7, 0), (2, 7, 8), (2, 7, 9)]


def test_nested_loops_and_a_return_from_inside_them(tmp_path):
    got = xs(tmp_path, """
        G1 F60
        o<grid> sub
          #<i>=0
          o10 while [#<i> LT 3]
            o11 repeat [2]
              o12 if [#<i> EQ 2]
                o<grid> return [#<i>]
              o12 endif
              G1 X[#<i>*10+#1]
            o11 endrepeat
            #<i>=[#<i>+1]
          o10 endwhile
        o<grid> endsub
        o<grid> call [1]
        G1 X#<_value>
        """)
    assert got == [1.0, 11.0, 2.0]  # 1, 1 (zero length: dropped), 11, 11, then the return value 2


def test_a_sub_may_be_defined_after_its_call_and_m2_inside_a_sub_ends(tmp_path):
    assert xs(tmp_path, "G1 F60\no9 call\nG1 X99\no9 sub\nG1 X1\nM2\no9 endsub\n") == [1.0]


def test_percent_and_block_delete_around_o_words(tmp_path):
    assert xs(tmp_path, "%\n/o1 if [0]\nG1 F60 X1\n/o1 endif\n%\no1 if [\n") == [1.0]


def test_a_program_number_is_ignored(tmp_path):
    assert xs(tmp_path, "O1000\nG1 F60 X1\nM30\n") == [1.0]


# =========================================================================== 4. errors

ERRORS = {
    "malformed": ("G1 F60 X1\nG1 X[1+]\n", 2, ["X[1+]", "a value is missing before ']'"]),
    "not a number": ("G1 F60 X1\nG1 X[1+.]\n", 2, ["X[1+.]", "'.]' is not a number"]),
    "unclosed bracket": ("G1 F60 X[1+2\n", 1, ["X[1+2", "not closed"]),
    "extra bracket": ("G1 F60 X[1+2]]\n", 1, ["']'", "not a word"]),
    "unknown function": ("G1 F60 X[FOO[1]]\n", 1, ["X[FOO[1]]", "'FOO' is not a function"]),
    "unknown operator": ("G1 F60 X[1 & 2]\n", 1, ["X[1&2]", "'&2]'", "not an operator"]),
    "division by zero": ("#1=0\nG1 F60 X[2/#1]\n", 2, ["X[2/#1]", "division by zero"]),
    "mod by zero": ("G1 F60 X[1 MOD 0]\n", 1, ["X[1MOD0]", "not a number"]),
    "undefined named": ("G1 F60 X#<depth>\n", 1, ["X#<depth>", "#<depth> is read before it is set"]),
    "sqrt": ("G1 F60 X[SQRT[-4]]\n", 1, ["SQRT[-4]", "negative"]),
    "ln": ("G1 F60 X[LN[0]]\n", 1, ["LN[0]", "positive"]),
    "acos": ("G1 F60 X[ACOS[2]]\n", 1, ["ACOS[2]", "outside [-1, 1]"]),
    "asin": ("G1 F60 Y[ASIN[-1.5]]\n", 1, ["ASIN[-1.5]", "outside [-1, 1]"]),
    "negative power": ("G1 F60 X[-8**[1/3]]\n", 1, ["non-integer power"]),
    "overflow": ("G1 F60 X[10**400]\n", 1, ["X[10**400]", "infinite"]),
    "atan one argument": ("G1 F60 X[ATAN[1]]\n", 1, ["ATAN[y]/[x]"]),
    "parameter range": ("G1 F60 X#5602\n", 1, ["#5602", "#1 to #5601"]),
    "parameter zero": ("#0=1\n", 1, ["#0", "#1 to #5601"]),
    "read-only": ("#5420=1\n", 1, ["#5420", "read-only"]),
    "read-only name": ("#<_x>=1\n", 1, ["#<_x>", "read-only"]),
    "no equals": ("#1 G1 X1\n", 1, ["without '='"]),
    "sub without endsub": ("G1 F60 X1\no100 sub\nG1 X2\n", 2, ["o100 sub", "no o100 endsub"]),
    "if without endif": ("G1 F60 X1\no1 if [1]\nG1 X2\nM2\n", 2, ["o1 if", "no o1 endif"]),
    "while without endwhile": ("o1 while [0]\nG1 F60 X2\n", 1, ["o1 while", "no o1 endwhile"]),
    "do without while": ("o1 do\nG1 F60 X2\n", 1, ["o1 do", "no o1 while"]),
    "repeat without end": ("o1 repeat [2]\nG1 F60 X2\n", 1, ["o1 repeat", "no o1 endrepeat"]),
    "mismatched label": ("o1 if [1]\nG1 F60 X2\no2 endif\n", 3, ["o2 endif", "o1 if of line 1"]),
    "endif alone": ("G1 F60 X1\no1 endif\n", 2, ["o1 endif without o1 if"]),
    "else twice": ("o1 if [1]\no1 else\no1 else\no1 endif\n", 3, ["o1 else after the o1 else of line 2"]),
    "unclosed inside sub": ("o1 sub\no2 if [1]\no1 endsub\n", 2, ["o2 if is not closed", "o1 endsub"]),
    "unknown sub": ("G1 F60 X1\no<pocket> call [1]\n", 2, ["o<pocket> call", "no subroutine o<pocket>"]),
    "break outside": ("o1 if [1]\no1 break\no1 endif\n", 2, ["o1 break", "not inside a while or do loop"]),
    "break of repeat": ("o1 repeat [2]\no1 break\no1 endrepeat\n", 2, ["o1 break", "repeat of line 1"]),
    "duplicate label": ("o1 if [1]\no1 endif\no1 while [0]\no1 endwhile\n", 3, ["o1 while", "duplicate"]),
    "nested sub": ("o1 sub\no2 sub\no2 endsub\no1 endsub\n", 2, ["o2 sub inside the o1 sub"]),
    "sub defined twice": ("o1 sub\no1 endsub\no1 sub\no1 endsub\n", 3, ["o1 sub", "already defined on line 1"]),
    "return outside": ("G1 F60 X1\no1 return\n", 2, ["o1 return outside a subroutine"]),
    "unknown command": ("o1 loop\n", 1, ["o1 loop", "not an O-word command"]),
    "condition missing": ("o1 if\no1 endif\n", 1, ["o1 if needs a value"]),
    "condition unbracketed": ("o1 while 1\no1 endwhile\n", 1, ["o1 while", "in brackets"]),
    "condition error": ("o1 if [#<nope>]\no1 endif\n", 1, ["o1 if [#<nope>]", "#<nope> is read before"]),
    "argument error": ("o1 sub\no1 endsub\no1 call [1] [1/0]\n", 3, ["o1 call [1/0]", "division by zero"]),
    "too many arguments": ("o1 sub\no1 endsub\no1 call" + " [1]" * 31 + "\n", 3, ["more than 30 arguments"]),
    "too deep": ("o1 sub\no1 call\no1 endsub\no1 call\n", 2, ["o1 call", "more than 9 nested calls"]),
    "stray O": ("G1 F60 X1 O2\n", 1, ["an O after the words"]),
    "Fanuc call": ("G1 F60 X1\nM98 P100\n", 2, ["M98", "O-word subroutines"]),
    "nested brackets": ("G1 F60 X" + "[" * 500 + "1" + "]" * 500 + "\n", 1, ["nested too deeply"]),
    "nested signs": ("G1 F60 X" + "-" * 3000 + "1\n", 1, ["nested too deeply"]),
    "nested parameters": ("G1 F60 X" + "#" * 3000 + "1\n", 1, ["nested too deeply"]),
    "text after": ("o1 if [1] G1 X1\no1 endif\n", 1, ["o1 if", "'G1X1' after its value"]),
}


@pytest.mark.parametrize("case", list(ERRORS))
def test_each_error_is_one_line_naming_file_line_and_word(tmp_path, case):
    text, line, parts = ERRORS[case]
    refused(tmp_path, text, line, *parts)


def test_a_runaway_loop_is_stopped_by_the_stated_limit(tmp_path):
    message = refused(tmp_path, "G1 F60 X1\no7 while [1]\no7 endwhile\n", 3, "o7 endwhile",
                      f"{MAX_REPEATED_LINES:,} lines", "never ends")
    assert MAX_REPEATED_LINES == 1_000_000, message


def test_the_limit_bounds_the_blocks_of_a_runaway(tmp_path, monkeypatch):
    """A runaway that moves: at most one block per executed line, so memory is bounded by the limit."""
    monkeypatch.setattr(program_module, "MAX_REPEATED_LINES", 2_000)
    refused(tmp_path, "G1 F60\n#1=0\no1 do\n#1=[#1+1]\nG1 X[#1 MOD 2]\no1 while [1]\n", 6, "o1 while",
            "2,000 lines")


def test_recursion_to_the_depth_limit_is_accepted(tmp_path):
    """Nine nested calls run (LinuxCNC's INTERP_SUB_ROUTINE_LEVELS is 10 frames, the main program's included)."""
    got = xs(tmp_path, "G1 F60\no1 sub\nG1 X#1\no2 if [#1 LT 9]\no1 call [#1+1]\no2 endif\no1 endsub\no1 call [1]\n")
    assert got == [float(n) for n in range(1, 10)]


def test_linuxcncs_loop_flags_are_kept(tmp_path):
    """LinuxCNC's doing_break outlives its break: the next do loop makes one pass (after a break, and after a
    while whose test failed with a break of its own in the body, skipped over); then it is cleared.
    rs274 2.9 moves exactly so: X1, Y1, Z1 Z2 Z3 (checked by hand; random programs in test_rs274_language.py)."""
    got = ends(tmp_path, """
        G1 F60
        #<i>=0
        o1 while [#<i> LT 5]
          #<i>=[#<i>+1]
          o2 if [#<i> EQ 2]
            o1 break
          o2 endif
        o1 endwhile
        #<j>=0
        o3 do
          #<j>=[#<j>+1]
          G1 X#<j>
        o3 while [#<j> LT 3]
        o4 while [0]
          o4 break
        o4 endwhile
        #<j>=0
        o5 do
          #<j>=[#<j>+1]
          G1 Y#<j>
        o5 while [#<j> LT 3]
        #<j>=0
        o6 do
          #<j>=[#<j>+1]
          G1 Z#<j>
        o6 while [#<j> LT 3]
        """)
    assert got == [(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 1, 2), (1, 1, 3)]


def test_a_continue_in_a_do_loop_inside_a_repeat_runs_away_as_in_linuxcnc(tmp_path, monkeypatch):
    """LinuxCNC leaves doing_continue set after a do loop's continue; the repeat around it, skipped to its end,
    loops back and starts again: rs274 never ends.  Here: the runaway error, naming the last jump back."""
    monkeypatch.setattr(program_module, "MAX_REPEATED_LINES", 5_000)
    path = program(tmp_path, "G1 F60 X1\no1 repeat [1]\n#<j>=0\no2 do\n#<j>=[#<j>+1]\no2 continue\n"
                           "o2 while [#<j> LT 2]\no1 endrepeat\n")
    with pytest.raises(SpecError) as info:
        read_gcode(str(path))
    message = str(info.value)  # the jump back last made: the continue's, the do's or the repeat's
    assert any(message.startswith(f"{path}:{n}: {o}: ") for n, o in ((6, "o2 continue"), (7, "o2 while"),
                                                                      (8, "o1 endrepeat"))), message
    assert "5,000 lines" in message and "never ends" in message


def test_reading_is_linear_in_the_program(tmp_path, monkeypatch):
    """Each line is cleaned at most twice (the O-word index, then execution), however many O-words: no rescans."""
    from nurbsinterp.config.gcode import words
    calls = []
    original = words.clean_line

    def counted(ctx, raw, number):
        calls.append(number)
        return original(ctx, raw, number)

    monkeypatch.setattr(program_module, "clean_line", counted)
    body = "".join(f"o{n} if [{n % 2}]\nG1 X{n}\no{n} else\nG1 Y{n}\no{n} endif\n" for n in range(1, 2001))
    path = program(tmp_path, "G1 F60\n" + body + "o9999 sub\nG1 Z1\no9999 endsub\no9999 call\n")
    read_gcode(str(path))
    lines = 1 + 5 * 2000 + 4
    assert len(calls) <= 2 * lines


def test_a_repeat_keeps_its_count_per_label_across_calls(tmp_path):
    """LinuxCNC keeps a repeat's count with its label: a return from inside the loop leaves the count, and the
    next call resumes it.  rs274 2.9 moves exactly so (checked by hand)."""
    got = ends(tmp_path, """
        G1 F60
        o1 sub
          o2 repeat [3]
            #<_n>=[#<_n>+1]
            G1 X#<_n>
            o3 if [#<_n> EQ 2]
              o1 return [7]
            o3 endif
          o2 endrepeat
        o1 endsub
        #<_n>=0
        o1 call
        G1 Y#<_value>
        o1 call
        G1 Y#<_value_returned>
        o1 call
        G1 Z1
        """)
    assert got == [(1, 0, 0), (2, 0, 0), (2, 7, 0), (3, 7, 0), (3, 0, 0), (4, 0, 0), (5, 0, 0), (6, 0, 0),
                   (6, 0, 1)]


@pytest.mark.parametrize("text, problem", [("N.5 G1 X1", "not a line number"), ("G1 X1 N5", "must come first"),
                                           ("G1 X1 X2", "given twice"), ("G1 X1 A2", "A is an axis"),
                                           ("G1 X1 E2", "E2 is given with no G-code"), ("G2.2 X1", "G2.2 is not a G-code"),
                                           ("G1 X1 M1.5", "M1.5 is not an M-code"),
                                           ("G1 X1" + "9" * 400, "too large a number")])
def test_plain_lines_read_quickly_are_refused_as_before(tmp_path, text, problem):
    """Lines of plain words take a quick path; whatever it does not take is read by the full reader, errors too."""
    refused(tmp_path, text + "\n", 1, problem)


#: the issue's list of what must be one line, exit 2, nothing written: through the commands themselves
ACCEPTANCE = ("malformed", "unclosed bracket", "unknown function", "division by zero", "undefined named",
              "sub without endsub", "while without endwhile", "unknown sub", "too deep")


@pytest.mark.parametrize("case", ACCEPTANCE)
def test_the_commands_refuse_each_in_one_line_writing_nothing(capsys, tmp_path, case):
    from test_cli_contract import one_line_error, run_main

    text, line, parts = ERRORS[case]
    bad = tmp_path / "bad.ngc"
    bad.write_text(text)
    for command, out_name in (("plan", "out.csv"), ("convert", "out.yaml"), ("info", None)):
        args = [command, bad] + (["-o", tmp_path / out_name] if out_name else [])
        code, out, err = run_main(capsys, *args)
        one_line_error(code, out, err, f"{bad}:{line}: ", *parts)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.ngc"]
