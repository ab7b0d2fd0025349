"""The relighting material of an imported lblight bake: the base solutions a sun lamp selects,
weighted (relight.weights), emitted by the medium's scattering, inside the medium's extinction.

Per channel c, in world units (lblight's sigma values are per voxel edge h):
    emission   = density * sigma_s[c] / (4 pi h) * sum_j w_j B_j[c]     (isotropic in-scattering)
    absorption = density * sigma_t[c] / h                               (Volume Absorption)
with the wood parameters where the `brown` grid is above 0.5. This is `lblight render --term lb`
(the whole LB light scattered isotropically), so the two agree; the emission is masked by the
density, so nothing glows outside the medium."""
import math

import bpy

PREFIX = "lblight_w_"  # nodes holding one base solution's weight: PREFIX + grid name


def _channels(material):
    sa, ss = material["sigma_a"], material["sigma_s"]
    return [float(a) + float(s) for a, s in zip(sa, ss)], [float(s) for s in ss]


def _constant_mix(nodes, links, fac_socket, a, b, location):
    """a + fac * (b - a) for constant 3-vectors a, b; returns the output socket."""
    scale = nodes.new("ShaderNodeVectorMath")
    scale.operation = "SCALE"
    scale.inputs[0].default_value = [y - x for x, y in zip(a, b)]
    links.new(fac_socket, scale.inputs["Scale"])
    add = nodes.new("ShaderNodeVectorMath")
    add.operation = "ADD"
    links.new(scale.outputs[0], add.inputs[0])
    add.inputs[1].default_value = a
    scale.location = location
    add.location = (location[0] + 200, location[1])
    return add.outputs[0]


def build(name, grids, medium, wood, voxel):
    """A material over `grids` (the B.. grids the bake holds) for the medium and wood materials of
    a bake's manifest (sigma_a, sigma_s per channel, per voxel length) and voxel edge `voxel`."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    out.location = (1400, 0)

    density = nodes.new("ShaderNodeAttribute")
    density.attribute_name = "density"
    density.location = (-800, 400)
    brown = nodes.new("ShaderNodeAttribute")
    brown.attribute_name = "brown"  # absent grids read 0: all medium
    brown.location = (-800, 200)
    is_wood = nodes.new("ShaderNodeMath")
    is_wood.operation = "GREATER_THAN"
    is_wood.inputs[1].default_value = 0.5
    links.new(brown.outputs["Fac"], is_wood.inputs[0])
    is_wood.location = (-600, 200)

    # Light: sum of weight x base solution.
    total = None
    y = 0
    for g in sorted(grids):
        attr = nodes.new("ShaderNodeAttribute")
        attr.attribute_name = g
        attr.location = (-800, -200 - y)
        w = nodes.new("ShaderNodeVectorMath")
        w.operation = "SCALE"
        w.name = PREFIX + g
        w.label = g + " weight"
        w.inputs["Scale"].default_value = 0.0
        links.new(attr.outputs["Vector"], w.inputs[0])
        w.location = (-600, -200 - y)
        if total is None:
            total = w.outputs[0]
        else:
            add = nodes.new("ShaderNodeVectorMath")
            add.operation = "ADD"
            links.new(total, add.inputs[0])
            links.new(w.outputs[0], add.inputs[1])
            add.location = (-400, -200 - y)
            total = add.outputs[0]
        y += 160

    st_m, ss_m = _channels(medium)
    st_w, ss_w = _channels(wood)
    k = 1.0 / (4 * math.pi * voxel)
    scatter = _constant_mix(nodes, links, is_wood.outputs[0], [s * k for s in ss_m], [s * k for s in ss_w], (-400, 400))
    emit = nodes.new("ShaderNodeVectorMath")
    emit.operation = "MULTIPLY"
    links.new(total, emit.inputs[0])
    links.new(scatter, emit.inputs[1])
    emit.location = (200, 200)
    emit_rho = nodes.new("ShaderNodeVectorMath")
    emit_rho.operation = "SCALE"
    links.new(emit.outputs[0], emit_rho.inputs[0])
    links.new(density.outputs["Fac"], emit_rho.inputs["Scale"])
    emit_rho.location = (400, 200)
    emission = nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    links.new(emit_rho.outputs[0], emission.inputs["Color"])
    emission.location = (700, 200)

    # Extinction per channel: Volume Absorption takes density D and colour C, sigma = D (1 - C).
    top = max(st_m + st_w)
    colour = _constant_mix(nodes, links, is_wood.outputs[0], [1 - s / top for s in st_m], [1 - s / top for s in st_w],
                           (-400, 700))
    dens = nodes.new("ShaderNodeMath")
    dens.operation = "MULTIPLY"
    links.new(density.outputs["Fac"], dens.inputs[0])
    dens.inputs[1].default_value = top / voxel
    dens.location = (400, 600)
    absorb = nodes.new("ShaderNodeVolumeAbsorption")
    links.new(colour, absorb.inputs["Color"])
    links.new(dens.outputs[0], absorb.inputs["Density"])
    absorb.location = (700, 500)
    both = nodes.new("ShaderNodeAddShader")
    links.new(emission.outputs[0], both.inputs[0])
    links.new(absorb.outputs[0], both.inputs[1])
    both.location = (1100, 300)
    links.new(both.outputs[0], out.inputs["Volume"])
    return mat


def set_weights(mat, weights):
    """Writes {grid: weight} into the material (0 for the rest); returns the grids it lacks.
    Writes only what changed, so a depsgraph handler calling it settles."""
    nodes = mat.node_tree.nodes
    missing = [g for g, w in weights.items() if w != 0.0 and nodes.get(PREFIX + g) is None]
    for node in nodes:
        if node.name.startswith(PREFIX):
            w = float(weights.get(node.name[len(PREFIX):], 0.0))
            if abs(node.inputs["Scale"].default_value - w) > 1e-9 * (1 + abs(w)):
                node.inputs["Scale"].default_value = w
    return missing
