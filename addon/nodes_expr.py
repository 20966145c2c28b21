"""A tiny expression-to-nodes builder for Cycles shader node trees.

Node mode must evaluate the same formulas as the OSL shader (``osl/include/loom/*.h``). Wiring
hundreds of Math nodes by hand would make a second, unreadable copy of that math; instead the
formulas are written once more as *Python expressions* that read like the headers, line by line,
and this module turns each operation into the node that computes it:

    open_ = 1.0 - clamp(c, 0.0, 1.0)          ->  Clamp node, Math SUBTRACT node
    V = vec(dot(Vw, T), dot(Vw, B), dot(Vw, N))  ->  3 Vector Math DOT_PRODUCT, Combine XYZ

``F`` wraps a float socket, ``V`` a vector (or colour) socket. Python numbers (3-tuples for
vectors) are constants, folded in Python or set as the nodes' default input values.

Semantics are Blender's nodes', which differ from OSL/C++ where the transcriptions rely on it:
division by zero gives 0 (Math DIVIDE, Vector Math SCALE with a safe inverse).
Branches (``if`` in the headers) become ``select(cond, a, b)``: both sides are evaluated and a
Mix node picks one with a 0/1 factor; the safe arithmetic above keeps the unused side finite.

Cycles' SVM runs every node at every shading point, so no value is computed twice: an operation
asked again on the same inputs returns the node made the first time (``Builder.op_node``), a
clamp of what is already inside its range and ``x + 0``, ``x * 1`` make no node.

The nodes are made by a ``nodes_builder.Builder``: inside ``with builder.block("title"):`` they go
in a frame with that title (the header function mirrored); ``builder.layout()`` places them.
"""

from __future__ import annotations

import math

# ------------------------------------------------------------------------------ expressions


class Expr:
    __slots__ = ("b", "socket")

    def __init__(self, b, socket):  # b: the nodes_builder.Builder that made the socket
        self.b = b
        self.socket = socket


def _builder(*args):  # -> the nodes_builder.Builder of the first expression, or None
    for a in args:
        if isinstance(a, Expr):
            return a.b
    return None


def is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def is_vector_constant(x) -> bool:
    return isinstance(x, (tuple, list)) and len(x) == 3 and all(is_number(c) for c in x)


_PY_MATH = {
    "ADD": lambda a, b: a + b,
    "SUBTRACT": lambda a, b: a - b,
    "MULTIPLY": lambda a, b: a * b,
    "DIVIDE": lambda a, b: a / b if b != 0 else 0.0,
    "POWER": lambda a, b: a ** b if a >= 0 else 0.0,
    "MINIMUM": min,
    "MAXIMUM": max,
    "LESS_THAN": lambda a, b: 1.0 if a < b else 0.0,
    "GREATER_THAN": lambda a, b: 1.0 if a > b else 0.0,
    "SQRT": lambda a: math.sqrt(a) if a > 0 else 0.0,
    "ABSOLUTE": abs,
    "LOGARITHM": lambda a, b: math.log(a) / math.log(b) if a > 0 and b > 0 else 0.0,
    "FLOOR": math.floor,
    "FRACT": lambda a: a - math.floor(a),
    "ARCTAN2": math.atan2,
    "PINGPONG": lambda a, b: abs((((a - b) / (2 * b)) - math.floor((a - b) / (2 * b))) * 2 * b - b)
    if b != 0 else 0.0,
    "SINE": math.sin,
    "COSINE": math.cos,
    "ARCSINE": lambda a: math.asin(a) if -1.0 <= a <= 1.0 else 0.0,
    "ARCCOSINE": lambda a: math.acos(a) if -1.0 <= a <= 1.0 else 0.0,
}


def math_op(op: str, *args) -> F | float:
    """Blender Math node ``op`` on scalars (expressions or numbers)."""
    b = _builder(*args)
    if b is None:
        return float(_PY_MATH[op](*args))
    if len(args) == 2 and is_number(args[1]) and (
            (op in ("ADD", "SUBTRACT") and args[1] == 0) or
            (op in ("MULTIPLY", "DIVIDE") and args[1] == 1)):
        return args[0]  # x + 0, x - 0, x 1, x / 1: x itself, no node
    if op in ("ADD", "MULTIPLY") and is_number(args[0]) and args[0] == (0 if op == "ADD" else 1):
        return args[1]
    node = b.op_node("ShaderNodeMath", {"operation": op}, list(enumerate(args)))
    if op in ("LESS_THAN", "GREATER_THAN"):
        b.ranges[node.name] = (0.0, 1.0)
    elif op == "MULTIPLY" and len(args) == 2:
        r = [_range(a) for a in args]
        k = [a for a in args if is_number(a)]
        if k and k[0] >= 0 and (r[0] or r[1]):
            lo, hi = r[0] or r[1]
            b.ranges[node.name] = (lo * k[0], hi * k[0])
    return F(b, node.outputs[0])


def _range(x):
    """The range an expression is known to lie in (Builder.ranges), or None."""
    return x.b.ranges.get(x.socket.node.name) if isinstance(x, F) else None


def _vec_math(op: str, *args, scale=None, out: str = "Vector"):
    b = _builder(*args, scale)
    inputs = list(enumerate(args)) + ([] if scale is None else [(3, scale)])
    node = b.op_node("ShaderNodeVectorMath", {"operation": op}, inputs)
    return V(b, node.outputs[0]) if out == "Vector" else F(b, node.outputs[1])


class F(Expr):
    """A float-valued expression."""

    __slots__ = ()

    def __add__(self, o):
        return math_op("ADD", self, o)

    def __radd__(self, o):
        return math_op("ADD", o, self)

    def __sub__(self, o):
        return math_op("SUBTRACT", self, o)

    def __rsub__(self, o):
        return math_op("SUBTRACT", o, self)

    def __mul__(self, o):
        if isinstance(o, V) or is_vector_constant(o):
            return scale(o, self)
        return math_op("MULTIPLY", self, o)

    def __rmul__(self, o):
        if is_vector_constant(o):
            return scale(o, self)
        return math_op("MULTIPLY", o, self)

    def __truediv__(self, o):
        return math_op("DIVIDE", self, o)

    def __rtruediv__(self, o):
        return math_op("DIVIDE", o, self)

    def __neg__(self):
        return math_op("MULTIPLY", self, -1.0)

    def __lt__(self, o):
        return math_op("LESS_THAN", self, o)

    def __gt__(self, o):
        return math_op("GREATER_THAN", self, o)


class V(Expr):
    """A vector-valued expression (colours too: Cycles converts colour <-> vector freely)."""

    __slots__ = ()

    @property
    def x(self) -> F:
        return self.b.separate(self)[0]

    @property
    def y(self) -> F:
        return self.b.separate(self)[1]

    @property
    def z(self) -> F:
        return self.b.separate(self)[2]

    def __getitem__(self, i: int) -> F:
        return self.b.separate(self)[i]

    def __add__(self, o):
        return _vec_math("ADD", self, o)

    def __radd__(self, o):
        return _vec_math("ADD", o, self)

    def __sub__(self, o):
        return _vec_math("SUBTRACT", self, o)

    def __rsub__(self, o):
        return _vec_math("SUBTRACT", o, self)

    def __mul__(self, o):
        if isinstance(o, V) or is_vector_constant(o):
            return _vec_math("MULTIPLY", self, o)  # component-wise, like OSL colour * colour
        return scale(self, o)

    def __rmul__(self, o):
        return self.__mul__(o)

    def __truediv__(self, o):
        if isinstance(o, V) or is_vector_constant(o):
            return _vec_math("DIVIDE", self, o)
        return scale(self, 1.0 / o)  # Math DIVIDE: 1/0 -> 0, so v/0 -> 0

    def __neg__(self):
        return scale(self, -1.0)


# ------------------------------------------------------------------------------- functions


def scale(v, s):
    """v * s for a vector v and a scalar s."""
    if is_vector_constant(v) and is_number(s):
        return tuple(c * s for c in v)
    return _vec_math("SCALE", v, scale=s)


def madd(a, b_, c):
    """a b + c in one node: Math MULTIPLY_ADD for scalars, Vector Math MULTIPLY_ADD (component-wise)
    when any operand is a vector."""
    if any(isinstance(v, V) or is_vector_constant(v) for v in (a, b_, c)):
        if _builder(a, b_, c) is None:
            return tuple(p * q + r for p, q, r in zip(*(v if is_vector_constant(v) else (v,) * 3
                                                        for v in (a, b_, c))))
        return _vec_math("MULTIPLY_ADD", a, b_, c)
    b = _builder(a, b_, c)
    if b is None:
        return float(a * b_ + c)
    node = b.op_node("ShaderNodeMath", {"operation": "MULTIPLY_ADD"}, list(enumerate((a, b_, c))))
    return F(b, node.outputs[0])


def vec(x, y, z):
    """Combine XYZ (a constant tuple when all three are numbers)."""
    b = _builder(x, y, z)
    if b is None:
        return (float(x), float(y), float(z))
    node = b.op_node("ShaderNodeCombineXYZ", {}, list(enumerate((x, y, z))))
    return V(b, node.outputs[0])


def dot(a, b_):
    if is_vector_constant(a) and is_vector_constant(b_):
        return sum(p * q for p, q in zip(a, b_))
    return _vec_math("DOT_PRODUCT", a, b_, out="Value")


def cross(a, b_):
    return _vec_math("CROSS_PRODUCT", a, b_)


def length(v):
    return _vec_math("LENGTH", v, out="Value")


def normalize(v):
    """Zero vector for a zero input, like OSL's normalize."""
    return _vec_math("NORMALIZE", v)


def sqrt(x):
    return math_op("SQRT", x)


def log(x):  # (Blender's Logarithm node: 0 for x <= 0)
    return math_op("LOGARITHM", x, math.e)


def fabs(x):
    return math_op("ABSOLUTE", x)


def floor(x):
    return math_op("FLOOR", x)


def fract(x):
    """x - floor(x), one Math node (FRACT)."""
    return math_op("FRACT", x)


def atan2(y, x):
    return math_op("ARCTAN2", y, x)


def sin(x):
    return math_op("SINE", x)


def cos(x):
    return math_op("COSINE", x)


def asin(x):
    """Math ARCSINE: 0 outside [-1, 1] (callers clamp, as the headers do)."""
    return math_op("ARCSINE", x)


def acos(x):
    """Math ARCCOSINE: 0 outside [-1, 1] (callers clamp, as the headers do)."""
    return math_op("ARCCOSINE", x)


def max_(a, b_):
    return math_op("MAXIMUM", a, b_)


def min_(a, b_):
    return math_op("MINIMUM", a, b_)


def vabs(v):
    """Vector Math ABSOLUTE: |v| per component."""
    return _vec_math("ABSOLUTE", v)


def vmax(a, b_):
    """Vector Math MAXIMUM, per component (a NaN component gives b's: a > b ? a : b)."""
    return _vec_math("MAXIMUM", a, b_)


def vmin(a, b_):
    return _vec_math("MINIMUM", a, b_)


def clamp(x, lo, hi):
    """OSL clamp(x, lo, hi) = min(max(x, lo), hi), one Clamp node (MINMAX)."""
    b = _builder(x, lo, hi)
    if b is None:
        return min(max(x, lo), hi)
    r = _range(x)
    if r is not None and is_number(lo) and is_number(hi) and lo <= r[0] and r[1] <= hi:
        return x  # already inside (a clamp, a comparison, a multiple of one): no node
    node = b.op_node("ShaderNodeClamp", {"clamp_type": "MINMAX"}, list(enumerate((x, lo, hi))))
    if is_number(lo) and is_number(hi):
        b.ranges[node.name] = (float(lo), float(hi))
    return F(b, node.outputs[0])


def select(cond, if_true, if_false):
    """``cond ? if_true : if_false`` for a 0/1 condition: a Mix node with the condition as its
    (clamped) factor, float or vector by the type of the operands."""
    b = _builder(cond, if_true, if_false)
    if b is None:
        return if_true if cond else if_false
    return _mix_node(b, cond, if_false, if_true, clamp_factor=True)


def mix(a, b_, t):
    """OSL mix(a, b, t) = a (1 - t) + b t, unclamped t, for scalars or vectors (a Mix node
    with clamping off; vectors with a uniform factor)."""
    b = _builder(a, b_, t)
    if b is None:
        return a * (1 - t) + b_ * t
    return _mix_node(b, t, a, b_, clamp_factor=False)


def _mix_node(b, t, a, b_, clamp_factor: bool):
    """A Mix node a (1 - t) + b_ t, float or vector (uniform factor) by the operands' type."""
    vector = any(isinstance(v, V) or is_vector_constant(v) for v in (a, b_))
    kind = "Vector" if vector else "Float"
    props = {"data_type": kind.upper(), "clamp_factor": clamp_factor}
    if vector:
        props["factor_mode"] = "UNIFORM"
    node = b.op_node("ShaderNodeMix", props, [("Factor_Float", t), ("A_" + kind, a),
                                              ("B_" + kind, b_)])
    out = socket_by_id(node.outputs, "Result_" + kind)
    return V(b, out) if vector else F(b, out)


def operand_key(v):
    """What identifies an operand of op_node: the socket of an expression, else the constant."""
    if isinstance(v, Expr):
        return ("socket", v.socket.node.name, v.socket.identifier)
    if isinstance(v, (tuple, list)):
        return ("vector", tuple(float(c) for c in v))
    return ("number", float(v))


def socket_by_id(sockets, identifier):
    for s in sockets:
        if s.identifier == identifier:
            return s
    raise KeyError(identifier)
