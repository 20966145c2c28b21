"""The builder that nodes_expr's expressions make their nodes with: a shader node tree's nodes
and links, each operation made once (``op_node``), frames per header function (``block``),
function groups (``call``) and a deterministic layout (``layout``)."""

from __future__ import annotations

import hashlib
import inspect
from contextlib import contextmanager

from .nodes_expr import Expr, F, V, is_number, is_vector_constant, operand_key, socket_by_id

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
        # (node type, properties, inputs) -> the node that computes it: an expression built
        # twice is one node (common subexpressions; see op_node)
        self._computed: dict[tuple, object] = {}
        # node name -> (lo, hi): what a node's first output is known to lie in (never NaN), so
        # that clamp() to a range holding it makes no node (see clamp)
        self.ranges: dict[str, tuple[float, float]] = {}
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

    def op_node(self, idname: str, props: dict, inputs: list):
        """The node of type ``idname`` with ``props`` fed ``inputs`` ((socket index or
        identifier, value) pairs), made once: asked again for the same operation on the same
        sockets and constants, it returns the node made the first time. The headers' functions
        recompute what their callers share (each closure-LUT or table read computes its own view
        angles); Cycles' SVM runs every node at every shading point, so each one counts. (A node
        the Mix Shader's two sides share runs before its jump, once: no side pays for the other.)"""
        key = (idname, tuple(sorted(props.items())),
               tuple((sel, operand_key(v)) for sel, v in inputs))
        node = self._computed.get(key)
        if node is not None:
            return node
        node = self.new(idname, **props)
        for sel, v in inputs:
            socket = node.inputs[sel] if isinstance(sel, int) else socket_by_id(node.inputs, sel)
            self.link(v, socket)
        self._computed[key] = node
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
            if isinstance(a, bool) or is_number(a) or is_vector_constant(a):
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
        use = ("ShaderNodeGroup", key, tuple(operand_key(a) for a in flat))
        node = self._computed.get(use)  # the same function of the same inputs: its node again
        if node is None:
            node = self.new("ShaderNodeGroup", label=fn.__name__)
            node.node_tree = group
            for k, a in enumerate(flat):
                self.link(a, node.inputs[k])
            self._computed[use] = node
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



def sync_sockets(group, in_out: str, wanted: list) -> None:
    """Give ``group`` the (name, type) sockets ``wanted`` on side ``in_out``, kept if it has them
    (other trees' Group nodes of it lose their links when a socket is removed)."""
    have = [s for s in group.interface.items_tree if s.item_type == "SOCKET" and s.in_out == in_out]
    if [(s.name, s.socket_type) for s in have] != wanted:
        for s in have:
            group.interface.remove(s)
        for n, kind in wanted:
            group.interface.new_socket(n, in_out=in_out, socket_type=kind)
