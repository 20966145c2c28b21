"""Cycles' BSDF nodes as closures: the node inputs that give a closure's own parameters (the
node mode groups of both tiers use them; see node_mode's docstring for Cycles' mappings)."""

from __future__ import annotations

from .nodes_expr import select, sqrt


def glossy_node_inputs(ax, ay):
    """Roughness and Anisotropy of a GGX Glossy BSDF node giving alpha_x = ax (along its Tangent)
    and alpha_y = ay; see node_mode's docstring for Cycles' mapping: Roughness = (ax ay)^(1/4),
    Anisotropy = 1 - sqrt(ax / ay) when ax <= ay, else sqrt(ay / ax) - 1."""
    r = sqrt(ax / ay)
    return sqrt(sqrt(ax * ay)), select(ax > ay, 1.0 / r - 1.0, 1.0 - r)


def ggx_glossy(b, label: str, color, ax, ay, normal, tangent):
    """A Glossy BSDF node (GGX) for microfacet("ggx", normal, tangent, ax, ay, 1, 0) * color
    (``b`` a nodes_expr.Builder)."""
    rough, aniso = glossy_node_inputs(ax, ay)
    gl = b.new("ShaderNodeBsdfGlossy", distribution="GGX", label=label)
    b.link(color, gl.inputs["Color"])
    b.link(rough, gl.inputs["Roughness"])
    b.link(aniso, gl.inputs["Anisotropy"])
    b.link(0.0, gl.inputs["Rotation"])
    b.link(normal, gl.inputs["Normal"])
    b.link(tangent, gl.inputs["Tangent"])
    return gl
