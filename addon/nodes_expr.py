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

Nodes made inside ``with builder.block("title"):`` go in a frame with that title (the header
function mirrored); ``builder.layout()`` places them deterministically.
"""

from __future__ import annotations

import hashlib
import inspect
import math
from contextlib import contextmanager

# ------------------------------------------------------------------------------------ builder


_SOCKET = {"F": "NodeSocketFloat", "V": "NodeSocketVector"}


class Builder:
    """Creates and links nodes in ``tree`` (a ShaderNodeTree, material or group)."""

    HIDE = {"ShaderNodeMath", "ShaderNodeVectorMath", "ShaderNodeSeparateXYZ",
            "ShaderNodeCombineXYZ", "ShaderNodeMix", "ShaderNodeClamp"}

    def __init__(self, tree, functions: dict | None = None):
        self.tree = tree
        # The function groups of this build (call()), shared by all the builders of one build.
        self.functions: dict = {} if functions is None else functions
        self._separate: dict[tuple[str, str], object] = {}
        self._blocks: list[tuple[object | None, list]] = [(None, [])]
        self._order: dict[str, int] = {}
        # node name -> names of the nodes feeding it (kept here: NodeSocket.links scans every
        # link of the tree, which makes a layout of a large group quadratic)
        self._inputs: dict[str, set[str]] = {}

    # -- structure
    @contextmanager
    def block(self, title: str):
        """Group the nodes made in this context in a frame labelled ``title``."""
        frame = self.tree.nodes.new("NodeFrame")
        frame.label = title
        frame.name = "Frame " + title[:48]
        frame.label_size = 14
        frame.shrink = True
        self._blocks.append((frame, []))
        try:
            yield frame
        finally:
            self._blocks.append((None, []))

    def new(self, idname: str, **props):
        node = self.tree.nodes.new(idname)
        for k, v in props.items():
            setattr(node, k, v)
        frame, members = self._blocks[-1]
        if frame is not None:
            node.parent = frame
        if idname in self.HIDE:
            node.hide = True
        members.append(node)
        self._order[node.name] = len(self._order)
        return node

    def link(self, value, socket) -> None:
        """Feed ``value`` (an expression, a number or a 3-tuple) into an input socket."""
        if isinstance(value, Expr):
            self.tree.links.new(value.socket, socket)
            self._inputs.setdefault(socket.node.name, set()).add(value.socket.node.name)
        elif isinstance(value, (tuple, list)):
            dv = socket.default_value
            if len(dv) == 4 and len(value) == 3:  # colour sockets are RGBA
                value = (*value, 1.0)
            socket.default_value = value
        else:
            socket.default_value = float(value)

    def connect(self, from_socket, to_socket) -> None:
        """Link two sockets (shader sockets, group sockets), recorded for the layout."""
        self.tree.links.new(from_socket, to_socket)
        self._inputs.setdefault(to_socket.node.name, set()).add(from_socket.node.name)

    def add_shaders(self, shaders):
        """The sum of shader output sockets as a chain of Add Shader nodes, in order (Cycles'
        SVM compiles the closures of such a chain in that order); returns the last output."""
        total = None
        for out in shaders:
            if total is None:
                total = out
                continue
            add = self.new("ShaderNodeAddShader")
            self.connect(total, add.inputs[0])
            self.connect(out, add.inputs[1])
            total = add.outputs["Shader"]
        return total

    def call(self, fn, *args, **static):
        """``fn(*args, **static)`` computed in a node group of its own, used here through a
        Group node; returns what fn returns, its expressions now the Group node's outputs.
        Expressions among ``args`` (also in lists) become the group's inputs, numbers and tuples
        constants inside it (constant results stay Python constants, so folding goes on);
        ``static`` (the header constants K) is passed as is. One group per function and
        constants, built once per build (``functions``; an earlier build's is rebuilt in place).
        Why: Blender's tree updates make building quadratic in a tree's size, while Cycles
        inlines groups into the same shader."""
        import bpy  # here only: the rest of this module does not need Blender

        flat: list[Expr] = []

        def describe(a):
            if isinstance(a, Expr):
                flat.append(a)
                return "V" if isinstance(a, V) else "F"
            if isinstance(a, (list, tuple)) and any(isinstance(x, Expr) for x in a):
                return [describe(x) for x in a]
            if isinstance(a, bool) or _is_num(a) or _is_vec_const(a):
                return ("const", a)
            raise TypeError(f"call({fn.__name__}): argument {a!r} is neither an expression "
                            f"nor a constant")

        desc = [describe(a) for a in args]
        if not flat:
            return fn(*args, **static)
        key = (fn.__module__, fn.__qualname__, repr(desc))
        entry = self.functions.get(key)
        if entry is None:
            digest = hashlib.sha1(repr(key).encode()).hexdigest()[:6]
            name = f"Loom fn {fn.__name__} {digest}"
            group = bpy.data.node_groups.get(name)
            if group is None or group.bl_idname != "ShaderNodeTree":
                group = bpy.data.node_groups.new(name, "ShaderNodeTree")
            # Rebuilt in place, its sockets kept where they are the same: other materials use
            # this group too, and their Group nodes lose their links when a socket goes.
            group.nodes.clear()
            group.description = f"Loom: {fn.__name__} ({fn.__module__}), as in the headers"
            params = list(inspect.signature(fn).parameters)
            names = []
            for k, (a, d) in enumerate(zip(args, desc)):
                base = params[k] if k < len(params) else f"arg{k}"
                if isinstance(d, list):
                    names += [(f"{base}[{j}]", x) for j, x in enumerate(d)]
                elif isinstance(d, str):
                    names.append((base, d))
            sync_sockets(group, "INPUT", [(n, _SOCKET[kind]) for n, kind in names])
            sub = Builder(group, self.functions)
            gin = sub.new("NodeGroupInput")
            inputs = iter(range(len(flat)))

            def rebuild(a, d):
                if isinstance(d, list):
                    return [rebuild(x, dx) for x, dx in zip(a, d)]
                if isinstance(d, str):
                    sock = gin.outputs[next(inputs)]
                    return sub.vector_socket(sock) if d == "V" else sub.float_socket(sock)
                return a

            result = fn(*[rebuild(a, d) for a, d in zip(args, desc)], **static)
            items = list(result) if isinstance(result, tuple) else [result]
            outs = []  # per result: the output socket's index and kind, or None (a constant)
            wanted = []
            for j, item in enumerate(items):
                if isinstance(item, Expr):
                    kind = "V" if isinstance(item, V) else "F"
                    wanted.append((f"out{j}", _SOCKET[kind]))
                    outs.append((sum(o is not None for o in outs), kind))
                else:
                    outs.append(None)
            sync_sockets(group, "OUTPUT", wanted)
            gout = sub.new("NodeGroupOutput")
            for item, o in zip(items, outs):
                if o is not None:
                    sub.connect(item.socket, gout.inputs[o[0]])
            sub.layout()
            entry = (group, outs, items, isinstance(result, tuple))
            self.functions[key] = entry
        group, outs, items, is_tuple = entry
        node = self.new("ShaderNodeGroup", label=fn.__name__)
        node.node_tree = group
        for k, a in enumerate(flat):
            self.link(a, node.inputs[k])
        got = [item if o is None else
               (self.vector_socket if o[1] == "V" else self.float_socket)(node.outputs[o[0]])
               for item, o in zip(items, outs)]
        return tuple(got) if is_tuple else got[0]

    def label(self, expr: Expr, text: str) -> Expr:
        """Name a quantity: the label of the node that computes it (shown on hidden nodes)."""
        if isinstance(expr, Expr):
            expr.socket.node.label = text
        return expr

    # -- leaves
    def float_socket(self, socket) -> F:
        return F(self, socket)

    def vector_socket(self, socket) -> V:
        return V(self, socket)

    def separate(self, v: V) -> tuple[F, F, F]:
        key = (v.socket.node.name, v.socket.identifier)
        node = self._separate.get(key)
        if node is None:
            node = self.new("ShaderNodeSeparateXYZ")
            self.link(v, node.inputs[0])
            self._separate[key] = node
        return tuple(F(self, node.outputs[i]) for i in range(3))

    # -- layout
    def layout(self, x0: float = 0.0, y0: float = 0.0, col_w: float = 170.0,
               gap: float = 90.0) -> None:
        """Place nodes: blocks left to right; inside a block, columns by dependency depth.
        The locations are written at once with foreach_set: setting ``location`` node by node
        updates the whole tree each time, quadratic in its size (seconds for a ray-wave group)."""
        placed: dict[str, tuple[float, float]] = {}
        x = x0
        for frame, members in self._blocks:
            if not members:
                continue
            names = {n.name for n in members}
            depth: dict[str, int] = {}
            for n in members:  # creation order is a topological order
                d = 0
                for src in self._inputs.get(n.name, ()):
                    if src in names:
                        d = max(d, depth.get(src, 0) + 1)
                depth[n.name] = d
            cols: dict[int, list] = {}
            for n in members:
                cols.setdefault(depth[n.name], []).append(n)
            width = 0.0
            for d in sorted(cols):
                y = y0
                cw = col_w
                for n in cols[d]:
                    placed[n.name] = (x + width, y)
                    y -= _node_height(n)
                    cw = max(cw, n.width + 30.0)
                width += cw
            x += width + gap
        nodes = self.tree.nodes
        flat = [0.0] * (2 * len(nodes))
        nodes.foreach_get("location", flat)
        for i, n in enumerate(nodes):
            if n.name in placed:
                flat[2 * i], flat[2 * i + 1] = placed[n.name]
        nodes.foreach_set("location", flat)


def _node_height(node) -> float:
    if node.hide:
        return 42.0
    if node.bl_idname == "ShaderNodeTexImage":
        return 290.0
    shown = sum(1 for s in node.inputs if s.enabled and not s.hide)
    shown += sum(1 for s in node.outputs if s.enabled and not s.hide)
    return 60.0 + 24.0 * shown


# ------------------------------------------------------------------------------ expressions


class Expr:
    __slots__ = ("b", "socket")

    def __init__(self, b: Builder, socket):
        self.b = b
        self.socket = socket


def _builder(*args) -> Builder | None:
    for a in args:
        if isinstance(a, Expr):
            return a.b
    return None


def _is_num(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _is_vec_const(x) -> bool:
    return isinstance(x, (tuple, list)) and len(x) == 3 and all(_is_num(c) for c in x)


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
    "ARCTAN2": math.atan2,
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
    node = b.new("ShaderNodeMath", operation=op)
    for i, a in enumerate(args):
        b.link(a, node.inputs[i])
    return F(b, node.outputs[0])


def _vec_math(op: str, *args, scale=None, out: str = "Vector"):
    b = _builder(*args, scale)
    node = b.new("ShaderNodeVectorMath", operation=op)
    for i, a in enumerate(args):
        b.link(a, node.inputs[i])
    if scale is not None:
        b.link(scale, node.inputs[3])
    return V(b, node.outputs[0]) if out == "Vector" else F(b, node.outputs[1])


def sync_sockets(group, in_out: str, wanted: list) -> None:
    """Give ``group`` the (name, type) sockets ``wanted`` on side ``in_out``, kept if it has them
    (other trees' Group nodes of it lose their links when a socket is removed)."""
    have = [s for s in group.interface.items_tree if s.item_type == "SOCKET" and s.in_out == in_out]
    if [(s.name, s.socket_type) for s in have] != wanted:
        for s in have:
            group.interface.remove(s)
        for n, kind in wanted:
            group.interface.new_socket(n, in_out=in_out, socket_type=kind)


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
        if isinstance(o, V) or _is_vec_const(o):
            return scale(o, self)
        return math_op("MULTIPLY", self, o)

    def __rmul__(self, o):
        if _is_vec_const(o):
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
        if isinstance(o, V) or _is_vec_const(o):
            return _vec_math("MULTIPLY", self, o)  # component-wise, like OSL colour * colour
        return scale(self, o)

    def __rmul__(self, o):
        return self.__mul__(o)

    def __truediv__(self, o):
        if isinstance(o, V) or _is_vec_const(o):
            return _vec_math("DIVIDE", self, o)
        return scale(self, 1.0 / o)  # Math DIVIDE: 1/0 -> 0, so v/0 -> 0

    def __neg__(self):
        return scale(self, -1.0)


# ------------------------------------------------------------------------------- functions


def scale(v, s):
    """v * s for a vector v and a scalar s."""
    if _is_vec_const(v) and _is_num(s):
        return tuple(c * s for c in v)
    return _vec_math("SCALE", v, scale=s)


def vec(x, y, z):
    """Combine XYZ (a constant tuple when all three are numbers)."""
    b = _builder(x, y, z)
    if b is None:
        return (float(x), float(y), float(z))
    node = b.new("ShaderNodeCombineXYZ")
    for i, c in enumerate((x, y, z)):
        b.link(c, node.inputs[i])
    return V(b, node.outputs[0])


def dot(a, b_):
    if _is_vec_const(a) and _is_vec_const(b_):
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
    node = b.new("ShaderNodeClamp", clamp_type="MINMAX")
    for i, a in enumerate((x, lo, hi)):
        b.link(a, node.inputs[i])
    return F(b, node.outputs[0])


def select(cond, if_true, if_false):
    """``cond ? if_true : if_false`` for a 0/1 condition: a Mix node with the condition as its
    (clamped) factor, float or vector by the type of the operands."""
    b = _builder(cond, if_true, if_false)
    if b is None:
        return if_true if cond else if_false
    vector = any(isinstance(v, V) or _is_vec_const(v) for v in (if_true, if_false))
    node = b.new("ShaderNodeMix", data_type="VECTOR" if vector else "FLOAT",
                 clamp_factor=True)
    if vector:
        node.factor_mode = "UNIFORM"
    kind = "Vector" if vector else "Float"
    b.link(cond, _by_id(node.inputs, "Factor_Float"))
    b.link(if_false, _by_id(node.inputs, "A_" + kind))
    b.link(if_true, _by_id(node.inputs, "B_" + kind))
    out = _by_id(node.outputs, "Result_" + kind)
    return V(b, out) if vector else F(b, out)


def mix(a, b_, t):
    """OSL mix(a, b, t) = a (1 - t) + b t, unclamped t, for scalars or vectors (a Mix node
    with clamping off; vectors with a uniform factor)."""
    b = _builder(a, b_, t)
    if b is None:
        return a * (1 - t) + b_ * t
    vector = any(isinstance(v, V) or _is_vec_const(v) for v in (a, b_))
    kind = "Vector" if vector else "Float"
    node = b.new("ShaderNodeMix", data_type=kind.upper(), clamp_factor=False)
    if vector:
        node.factor_mode = "UNIFORM"
    b.link(t, _by_id(node.inputs, "Factor_Float"))
    b.link(a, _by_id(node.inputs, "A_" + kind))
    b.link(b_, _by_id(node.inputs, "B_" + kind))
    out = _by_id(node.outputs, "Result_" + kind)
    return V(b, out) if vector else F(b, out)


def _by_id(sockets, identifier):
    for s in sockets:
        if s.identifier == identifier:
            return s
    raise KeyError(identifier)
