"""The materials of imported lblight volumes (docs/blender.md).

Two kinds, one rendering formula (`_emission` and `_extinction`, each written once):

- "base": a bake's base solutions, relit per object. The material binds the 14 grids any sun at
  or above an object's horizon, its ambient and its sky can select (relight.HEMISPHERE: B00 and the
  13 level-or-downward directions, those the bake holds) plus density and brown: at most 16 grids,
  EEVEE's limit. The weights are not in the material: each object (or the collection-instance
  Empty that shows it) carries them as custom properties lblight_w0..lblight_w4 (3 floats each, in
  the order of SLOTS), read by Attribute nodes of type INSTANCER (the instancer's property, else the
  object's), so one material serves every instance and linked duplicate, each lit for the sun as
  it stands. EEVEE reads at most 8 such per-object attributes; this uses 6 (with lblight_unit).
- "static": a relit volume (`lblight relight`) or a static bake: emission from its `light` grid.

Per channel c, in world units (lblight's sigma values are per voxel edge h; an object scaled by s
keeps its optical depth per voxel, so per world unit they are divided by s: `lblight_unit` = 1/s):
    emission   = density * sigma_s[c] / (4 pi h s) * light[c]           (isotropic in-scattering)
    absorption = density * sigma_t[c] / (h s)                          (Volume Absorption)
    light      = sum_j w_j B_j  (base)   or the `light` grid (static)
with the wood parameters where the `brown` grid is above 0.5. This is `lblight render --term lb`
(the whole LB light scattered isotropically), so the two agree; the emission is masked by the
density, so nothing glows outside the medium."""
import math

import bpy

from . import relight

SLOTS = list(relight.HEMISPHERE)  # the base solutions a "base" material can bind, in weight order
# 3 weights per property, read as the Attribute node's Color. Not 4: Cycles divides a 4-float
# property's colour by its alpha (measured: weights (0.01, 0.01, 0.64, 0.02) gave B12 x 50).
PER_PROP = 3
WEIGHT_PROPS = ["lblight_w%d" % i for i in range((len(SLOTS) + PER_PROP - 1) // PER_PROP)]
UNIT_PROP = "lblight_unit"  # 1 / the object's scale (the cube root of its matrix's determinant)
KIND = "lblight_kind"  # material property: "base" or "static"


def _channels(material):
    sa, ss = material["sigma_a"], material["sigma_s"]
    return [float(a) + float(s) for a, s in zip(sa, ss)], [float(s) for s in ss]


class _Graph:
    def __init__(self, mat):
        self.nodes, self.links = mat.node_tree.nodes, mat.node_tree.links

    def node(self, kind, location, **settings):
        n = self.nodes.new(kind)
        n.location = location
        for k, v in settings.items():
            setattr(n, k, v)
        return n

    def link(self, a, b):
        self.links.new(a, b)

    def attribute(self, name, location, kind="GEOMETRY"):
        return self.node("ShaderNodeAttribute", location, attribute_name=name, attribute_type=kind)

    def vmath(self, op, location, a=None, b=None, scale=None):
        n = self.node("ShaderNodeVectorMath", location, operation=op)
        for sock, v in ((n.inputs[0], a), (n.inputs[1], b), (n.inputs["Scale"], scale)):
            if v is None:
                continue
            if isinstance(v, bpy.types.NodeSocket):
                self.link(v, sock)
            else:
                sock.default_value = v
        return n.outputs[0] if op != "LENGTH" else n.outputs["Value"]

    def math(self, op, location, a, b):
        n = self.node("ShaderNodeMath", location, operation=op)
        for sock, v in ((n.inputs[0], a), (n.inputs[1], b)):
            if isinstance(v, bpy.types.NodeSocket):
                self.link(v, sock)
            else:
                sock.default_value = v
        return n.outputs[0]

    def constant_mix(self, fac, a, b, location):
        """a + fac * (b - a) for constant 3-vectors a, b."""
        scaled = self.vmath("SCALE", location, a=[y - x for x, y in zip(a, b)], scale=fac)
        return self.vmath("ADD", (location[0] + 200, location[1]), a=scaled, b=a)


def _new(name, kind, medium, wood, voxel):
    """The material and the sockets every kind shares: density, wood mask and 1/s per world unit."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    mat.node_tree.nodes.clear()
    mat[KIND] = kind
    g = _Graph(mat)
    density = g.attribute("density", (-900, 500)).outputs["Fac"]
    brown = g.attribute("brown", (-900, 300)).outputs["Fac"]  # absent grids read 0: all medium
    is_wood = g.math("GREATER_THAN", (-700, 300), brown, 0.5)
    unit = g.attribute(UNIT_PROP, (-900, 700), "INSTANCER").outputs["Fac"]
    per_length = g.math("MULTIPLY", (-700, 600), density, unit)  # density / s: per world unit
    return mat, g, per_length, is_wood


def _emission_factor(g, per_length, is_wood, medium, wood, voxel):
    """The emission term's factor (with _emission, the one place the formula is written): what
    multiplies the LB light to give the radiance emitted per world unit, per_length x sigma_s[c] /
    (4 pi h): the light scattered isotropically (`lblight render --term lb`)."""
    _, ss_m = _channels(medium)
    _, ss_w = _channels(wood)
    k = 1.0 / (4 * math.pi * voxel)
    scatter = g.constant_mix(is_wood, [s * k for s in ss_m], [s * k for s in ss_w], (-300, 300))
    return g.vmath("SCALE", (100, 300), a=scatter, scale=per_length)


def _emission(g, light, factor, location):
    """The Emission shader of `light` (an LB light: a grid, or weight x grid): light[c] x factor[c]."""
    colour = g.vmath("MULTIPLY", (location[0] - 200, location[1]), a=light, b=factor)
    emission = g.node("ShaderNodeEmission", location)
    emission.inputs["Strength"].default_value = 1.0
    g.link(colour, emission.inputs["Color"])
    return emission.outputs[0]


def _extinction(g, per_length, is_wood, medium, wood, voxel):
    """per_length x sigma_t[c] / h as Volume Absorption (density D, colour C: sigma = D (1 - C))."""
    st_m, _ = _channels(medium)
    st_w, _ = _channels(wood)
    top = max(st_m + st_w)
    colour = g.constant_mix(is_wood, [1 - s / top for s in st_m], [1 - s / top for s in st_w], (-300, 700))
    dens = g.math("MULTIPLY", (400, 600), per_length, top / voxel)
    absorb = g.node("ShaderNodeVolumeAbsorption", (700, 500))
    g.link(colour, absorb.inputs["Color"])
    g.link(dens, absorb.inputs["Density"])
    return absorb.outputs[0]


def _finish(g, shaders):
    total = shaders[0]
    for i, sh in enumerate(shaders[1:]):
        add = g.node("ShaderNodeAddShader", (1100, 300 - 160 * i))
        g.link(total, add.inputs[0])
        g.link(sh, add.inputs[1])
        total = add.outputs[0]
    out = g.node("ShaderNodeOutputMaterial", (1300, 300))
    g.link(total, out.inputs["Volume"])


def build_base(name, grids, medium, wood, voxel):
    """A "base" material over the SLOTS grids among `grids` (the B.. grids the bake holds), for the
    medium and wood materials of a bake's manifest (sigma_a, sigma_s per channel, per voxel
    length) and voxel edge `voxel`. The weights come from each object's WEIGHT_PROPS.

    Each grid's emission (weight x grid) is its own Emission shader behind a Mix Shader whose factor
    is 1 where the object's weight for it is above 0 and 0 elsewhere: Cycles then skips the grids a
    sun leaves out (its SVM jumps over a zero-weight mix branch with the nodes only it uses), so a
    sample reads the 2-4 grids of the object's sun, not all 14 (measured on the default tree,
    160x120, 16 samples: 4.0 s, against 11.7 s for one weighted sum of every grid and 1.7 s for
    weights fixed in the material). The sum of the emissions is the emission of the sum."""
    mat, g, per_length, is_wood = _new(name, "base", medium, wood, voxel)
    bound = [s for s in SLOTS if s in grids]
    if not bound:
        raise ValueError("no base solution to bind")
    mat["lblight_grids"] = ",".join(bound)
    parts = {}
    for i, prop in enumerate(WEIGHT_PROPS):
        a = g.attribute(prop, (-1500, -300 - 500 * i), "INSTANCER")
        sep = g.node("ShaderNodeSeparateXYZ", (-1300, -300 - 500 * i))
        g.link(a.outputs["Color"], sep.inputs[0])
        parts[prop] = [sep.outputs[0], sep.outputs[1], sep.outputs[2]]
    factor = _emission_factor(g, per_length, is_wood, medium, wood, voxel)
    shaders = [_extinction(g, per_length, is_wood, medium, wood, voxel)]
    for y, grid in enumerate(bound):
        i = SLOTS.index(grid)
        weight = parts[WEIGHT_PROPS[i // PER_PROP]][i % PER_PROP]
        at = -200 - 160 * y
        b = g.attribute(grid, (-500, at))
        light = g.vmath("SCALE", (-300, at), a=b.outputs["Vector"], scale=weight)
        used = g.math("GREATER_THAN", (-300, at - 80), weight, 0.0)  # weights are never negative
        mix = g.node("ShaderNodeMixShader", (900, at))
        mix.label = grid
        g.link(used, mix.inputs["Fac"])
        g.link(_emission(g, light, factor, (700, at)), mix.inputs[2])
        shaders.append(mix.outputs[0])
    _finish(g, shaders)
    return mat


def build_static(name, medium, wood, voxel):
    """A "static" material: the emission of the volume's `light` grid (a relit volume)."""
    mat, g, per_length, is_wood = _new(name, "static", medium, wood, voxel)
    light = g.attribute("light", (-900, 100)).outputs["Vector"]
    factor = _emission_factor(g, per_length, is_wood, medium, wood, voxel)
    _finish(g, [_emission(g, light, factor, (700, 200)), _extinction(g, per_length, is_wood, medium, wood, voxel)])
    return mat


def kind(mat):
    return mat.get(KIND) if mat is not None else None


def object_values(weights, unit):
    """{property: value} an object carries for {grid: weight} and its 1/scale."""
    values = {UNIT_PROP: float(unit)}
    for i, prop in enumerate(WEIGHT_PROPS):
        values[prop] = [float(weights.get(s, 0.0)) for s in (SLOTS[PER_PROP * i:PER_PROP * (i + 1)] + [None] * PER_PROP)[:PER_PROP]]
    return values


def missing(mat, weights):
    """The grids `weights` asks for that the material does not bind (the bake left them out)."""
    bound = set(str(mat.get("lblight_grids", "")).split(","))
    return sorted(g for g, w in weights.items() if w != 0.0 and g not in bound)
