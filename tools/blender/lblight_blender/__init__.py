"""lblight for Blender: import an lblight bake as Volume objects whose light follows a Sun lamp,
each object lit in its own frame (docs/blender.md). File > Import > lblight, or from Python:

    import lblight_blender
    obj = lblight_blender.import_bake("out/default/tree.vdb")       # a model (or the folder + model=)
    lblight_blender.import_bake("out/forest/manifest.json")         # a forest: models once, instances
    lblight_blender.import_bake("tree-light.vdb")                   # `lblight relight`: a fixed sun
    lblight_blender.configure_cycles(bpy.context.scene)             # optional: the comparison's settings

A handler turns the lamp's direction into every object's own frame (the normalized inverse of its
world matrix), computes the base solutions' weights there (32-face decomposition, as `lblight
sun-weights`; none for a sun below that frame's horizon) and stores them on the object, or on the
collection-instance Empty that shows it, where the material's per-object Attribute nodes read
them. Import changes no scene setting unless asked to (the operator's "Set up scene")."""

bl_info = {
    "name": "lblight bakes",
    "author": "lblight",
    "version": (1, 1, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > lblight bake; Object properties > lblight",
    "description": "Import lblight lattice-Boltzmann light bakes, relit per object from a Sun lamp",
    "category": "Import-Export",
}

import math
import os

import bpy
from bpy.app.handlers import persistent
from bpy.props import BoolProperty, FloatProperty, StringProperty
from bpy_extras.io_utils import ImportHelper
from mathutils import Matrix, Vector

from . import inputs
from . import material as lbmaterial
from . import relight

InputError = inputs.InputError

# A lamp's rotation is float32: sun weights below this are its rounding, not light.
LAMP_NEGLIGIBLE = 1e-5
# lblight intensity per unit of a Sun lamp's Strength. A Blender Sun of Strength E delivers an
# irradiance of E (W/m^2) to a surface facing it; lblight's unit sun is the light whose open-air
# value is 1, i.e. irradiance 1 in the same units: the material then emits what Cycles' own Volume
# Scatter would scatter once from that lamp, and the tree is lit as Blender's surfaces are
# (docs/blender.md, "Sun strength and exposure").
SUN_UNIT = 1.0


# --- finding the lit objects -------------------------------------------------------------------

def _lb_volume(obj):
    """obj if it is a Volume with an lblight material, else None."""
    if obj is not None and obj.type == "VOLUME" and lbmaterial.kind(obj.active_material):
        return obj
    return None


def _instanced_volume(obj):
    """The lblight Volume a collection-instance Empty shows (the first of its collection), or None."""
    if obj.instance_type != "COLLECTION" or obj.instance_collection is None:
        return None
    return next((o for o in obj.instance_collection.all_objects if _lb_volume(o)), None)


def lit_objects(scene):
    """(holder, volume, frame) for every lblight volume the scene shows: a Volume object (holder =
    itself) and each collection-instance Empty of one (holder = the Empty); frame is the matrix
    from the volume's own space to the world."""
    for obj in scene.objects:
        if _lb_volume(obj):
            yield obj, obj, obj.matrix_world
        else:
            inner = _instanced_volume(obj)
            if inner is not None:
                offset = Matrix.Translation(-obj.instance_collection.instance_offset)
                yield obj, inner, obj.matrix_world @ offset @ inner.matrix_basis


def _setting(obj, key, default, inner=None):
    """A per-object setting: the object's, else its parents' (a forest's root), else the volume's."""
    o = obj
    while o is not None:
        if key in o:
            return o[key]
        o = o.parent
    if inner is not None and key in inner:
        return inner[key]
    return default


def _sun_lamp(scene, name):
    lamp = scene.objects.get(name) if name else None
    if lamp is not None and lamp.type == "LIGHT":
        return lamp
    return next((o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN"), None)


def sun_in_frame(lamp, frame):
    """(toward the sun in the world, the same in the frame's own axes (unit), 1 / the frame's scale)."""
    toward = (lamp.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))).normalized()  # a sun shines along its -Z
    m = frame.to_3x3()
    det = m.determinant()
    if abs(det) < 1e-30:
        return toward, None, 0.0
    return toward, (m.inverted() @ toward).normalized(), 1.0 / abs(det) ** (1.0 / 3.0)


def _elevation_azimuth(v):
    return (math.degrees(math.asin(max(-1.0, min(1.0, v.z)))),
            math.degrees(math.atan2(v.y, v.x)) % 360.0 if abs(v.z) < 1.0 - 1e-12 else 0.0)


def _write(obj, key, value):
    """Sets a custom property when it changed; True when it did."""
    old = obj.get(key)
    if isinstance(value, list):
        if old is not None and len(old) == len(value) and all(abs(a - b) <= 1e-9 * (1 + abs(b)) for a, b in zip(old, value)):
            return False
    elif isinstance(value, float):
        if isinstance(old, float) and abs(old - value) <= 1e-9 * (1 + abs(value)):
            return False
    elif old == value:
        return False
    obj[key] = value
    return True


_LAST = {}  # holder pointer -> (what its weights were computed from, the weights)


def relight_object(holder, scene, inner=None, frame=None):
    """Computes and stores the holder's weights for the scene's Sun lamp, in its own frame; returns
    {grid: weight} ({} for a static volume). holder: a lit Volume object or a collection-instance
    Empty of one (then inner and frame are found when not given)."""
    if inner is None:
        inner = _lb_volume(holder) or _instanced_volume(holder)
        if inner is None:
            return {}
    if frame is None:
        frame = next((f for h, v, f in lit_objects(scene) if h == holder), None)
        if frame is None:  # not in the scene: its own matrices
            frame = holder.matrix_world if holder == inner else holder.matrix_world @ inner.matrix_basis
    mat = inner.active_material
    lamp = _sun_lamp(scene, _setting(holder, "lblight_sun", "", inner))
    ambient = float(_setting(holder, "lblight_ambient", 0.0, inner))
    sky = float(_setting(holder, "lblight_sky", 0.0, inner))
    # Nothing moved since the last call: keep what the holder carries (a forest of thousands of
    # instances sees a depsgraph update on every edit).
    key = (tuple(v for row in frame for v in row), None if lamp is None else
           (tuple(v for row in lamp.matrix_world for v in row), float(lamp.data.energy)),
           ambient, sky, mat.name if mat else None, SUN_UNIT)
    cached = _LAST.get(holder.as_pointer())
    if cached is not None and cached[0] == key and lbmaterial.UNIT_PROP in holder:
        return cached[1]
    if lamp is None:
        toward, local, unit = None, None, 1.0 / max(1e-30, abs(frame.to_3x3().determinant())) ** (1.0 / 3.0)
    else:
        toward, local, unit = sun_in_frame(lamp, frame)
    changed = False
    if lbmaterial.kind(mat) == "base":
        if local is None:
            w = relight.frame_weights((0.0, 0.0, 1.0), 0.0, ambient, sky)
        else:
            w = relight.frame_weights(tuple(local), SUN_UNIT * float(lamp.data.energy), ambient, sky,
                                      negligible=LAMP_NEGLIGIBLE)
        values = lbmaterial.object_values(w, unit)
        gone = lbmaterial.missing(mat, w)
        note = ",".join(gone)
        if note and holder.get("lblight_missing", "") != note:
            print(f"lblight: {holder.name}: this sun needs {', '.join(gone)}, which the bake left out (its sun_range "
                  "or instance_rotation excludes it); those weights are dropped")
    else:
        w = {}
        values = {lbmaterial.UNIT_PROP: float(unit)}
        note = ""
    for k, v in values.items():
        changed |= _write(holder, k, v)
    if note:
        changed |= _write(holder, "lblight_missing", note)
    elif "lblight_missing" in holder:
        del holder["lblight_missing"]
        changed = True
    below = local is not None and local.z < 0.0
    if bool(holder.get("lblight_below", False)) != below:
        holder["lblight_below"] = below
        changed = True
    if changed:
        holder.update_tag()
    _LAST[holder.as_pointer()] = (key, w)
    return w


@persistent
def _follow_sun(scene, depsgraph=None):
    for holder, inner, frame in list(lit_objects(scene)):
        relight_object(holder, scene, inner, frame)


# --- importing -----------------------------------------------------------------------------------

class _Created:
    """The datablocks an import made, removed again when it fails half-way."""

    def __init__(self):
        self.ids = []

    def add(self, idb):
        self.ids.append(idb)
        return idb

    def undo(self):
        for idb in reversed(self.ids):
            try:
                if isinstance(idb, bpy.types.Object):
                    bpy.data.objects.remove(idb, do_unlink=True)
                elif isinstance(idb, bpy.types.Collection):
                    bpy.data.collections.remove(idb)
                elif isinstance(idb, bpy.types.Material):
                    bpy.data.materials.remove(idb)
                elif isinstance(idb, bpy.types.Volume):
                    bpy.data.volumes.remove(idb)
            except ReferenceError:
                pass
        self.ids = []


def _volume(made, name, vdb):
    vol = made.add(bpy.data.volumes.new(name))
    vol.filepath = vdb
    vol.render.precision = "FULL"  # light values are not fractions of 1: keep float32
    vol.render.clipping = 0.0
    if not vol.grids.load():
        raise InputError(f"{vdb}: Blender cannot load it ({vol.grids.error_message or 'no reason given'})")
    return vol


def _half_voxel(obj, voxel):
    # Blender draws a grid's voxel (i, j, k) over the cell [i, i+1]^3 of index space; OpenVDB,
    # Houdini and lblight put its value at the point (i, j, k). Half a voxel back so the light sits
    # where it was solved (measured: without it a 160x120 picture of the default tree differs from
    # lblight render's by 20% pixel-wise, with it by 1%).
    obj.location = [-0.5 * float(h) for h in voxel]


def _model_object(made, p, name, collection):
    vol = _volume(made, name or p["name"], p["vdb"])
    have = [g.name for g in vol.grids]
    mat = made.add(lbmaterial.build_base(f"lblight {p['name']}", have, p["medium"], p["wood"], p["voxel"][0]))
    vol.materials.append(mat)
    obj = made.add(bpy.data.objects.new(name or p["name"], vol))
    _half_voxel(obj, p["voxel"])
    collection.objects.link(obj)
    obj["lblight_model"] = p["name"]
    return obj


def _static_object(made, p, name, collection):
    vol = _volume(made, name or p["name"], p["vdb"])
    grid = vol.grids.get("density") or vol.grids.get("light")
    m = grid.matrix_object
    voxel = p["voxel"] or [m.col[i].to_3d().length for i in range(3)]
    mat = made.add(lbmaterial.build_static(f"lblight {p['name']}", p["medium"], p["wood"], float(voxel[0])))
    vol.materials.append(mat)
    obj = made.add(bpy.data.objects.new(name or p["name"], vol))
    _half_voxel(obj, voxel)
    collection.objects.link(obj)
    obj["lblight_model"] = p["name"]
    sun = p.get("sun") or {}
    if sun.get("sun_elevation") is not None:
        obj["lblight_static"] = ("relit by lblight relight: sun elevation %g, azimuth %g, intensity %g, ambient %g, sky %g"
                                 % tuple(float(sun.get(k) or 0.0) for k in ("sun_elevation", "sun_azimuth", "intensity",
                                                                             "ambient", "sky")))
    else:
        obj["lblight_static"] = "a static bake's light (the scene's sun)"
    if p.get("note"):
        obj["lblight_note"] = p["note"]
    return obj


def _forest(made, p, name, collection, scene):
    top = made.add(bpy.data.collections.new(f"lblight {name or p['name']}"))
    collection.children.link(top)
    sources = {}
    for model, mp in p["models"].items():
        src = made.add(bpy.data.collections.new(f"lblight {name or p['name']} {model}"))
        top.children.link(src)
        _model_object(made, mp, model, src)
        sources[model] = src
    # The models' own collections are the instances' sources: left out of every view layer, so only
    # the instances render.
    for layer in scene.view_layers:
        def find(lc):
            if lc.collection == top:
                return lc
            return next((r for r in (find(c) for c in lc.children) if r is not None), None)
        lc = find(layer.layer_collection)
        if lc is not None:
            for child in lc.children:
                child.exclude = True
    root = made.add(bpy.data.objects.new(name or p["name"], None))
    root.empty_display_type = "ARROWS"
    top.objects.link(root)
    root["lblight_forest"] = p["manifest"]
    for i, inst in enumerate(p["instances"]):
        e = made.add(bpy.data.objects.new(f"{inst['model']}.{i:04d}", None))
        e.instance_type = "COLLECTION"
        e.instance_collection = sources[inst["model"]]
        e.empty_display_size = 0.5
        e.parent = root
        # lblight's instance: world = position + scale * Rz(yaw) * p, p in the model's frame.
        e.location = inst["position"]
        e.rotation_euler = (0.0, 0.0, math.radians(inst["yaw_degrees"]))
        e.scale = (inst["scale"],) * 3
        e["lblight_instance"] = i
        e["lblight_model"] = inst["model"]
        top.objects.link(e)
    return root


def import_bake(path, model=None, name=None, sun=None, ambient=0.0, sky=0.0, bake=None, forest=None,
                scene=None, collection=None):
    """Imports what `path` is and returns its object: a model of an lblight bake (its .vdb, or the
    bake folder and `model`) as a Volume object relit per object by the Sun lamp; a relit volume
    (`lblight relight`) as a static Volume (`bake`: its bake folder, for the materials, when its
    lblight_source is not found); a forest bake (its manifest.json, folder or forest.vdb; `forest`
    True/False forces or refuses it) as each model's volume once in a collection plus one
    collection-instance Empty per instance under a root Empty (returned). Raises InputError naming
    the file and the reason; then nothing was added. Changes no scene setting."""
    scene = scene or bpy.context.scene
    collection = collection or scene.collection
    p = inputs.plan(os.path.abspath(bpy.path.abspath(path)), model=model,
                    bake=os.path.abspath(bpy.path.abspath(bake)) if bake else None, forest=forest)
    made = _Created()
    try:
        if p["kind"] == "model":
            obj = _model_object(made, p, name, collection)
        elif p["kind"] == "static":
            obj = _static_object(made, p, name, collection)
        else:
            obj = _forest(made, p, name, collection, scene)
        obj["lblight_sun"] = sun or ""
        obj["lblight_ambient"] = float(ambient)
        obj["lblight_sky"] = float(sky)
        for holder, inner, frame in list(lit_objects(scene)):
            if holder == obj or holder.parent == obj:
                relight_object(holder, scene, inner, frame)
        if p["kind"] != "forest" and obj.name not in scene.objects:  # linked outside the scene
            relight_object(obj, scene)
    except BaseException:
        made.undo()
        raise
    return obj


def configure_cycles(scene, samples=16):
    """Cycles settings under which the material is what `lblight render --term lb` computes: no
    volume bounces (the LB solution holds the multiple scattering), a black world, linear film,
    and the denoiser off where the build has none (Debian's: "Build without OpenImageDenoiser").
    Import never calls it unless asked (the operator's "Set up scene")."""
    import _cycles

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    if not getattr(_cycles, "with_openimagedenoise", False):
        scene.cycles.use_denoising = False
        scene.cycles.use_preview_denoising = False
    scene.cycles.volume_bounces = 0
    scene.cycles.max_bounces = 0
    scene.render.film_transparent = True
    scene.view_settings.view_transform = "Standard"
    if scene.world is None:
        scene.world = bpy.data.worlds.new("lblight black")
    scene.world.use_nodes = True
    bg = scene.world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Strength"].default_value = 0.0


SETUP_DESCRIPTION = ("Also change the scene for the lblight comparison: render engine Cycles on the CPU, max and "
                     "volume bounces 0, world strength 0, film transparent, view transform Standard, denoising "
                     "off where this Blender has no OpenImageDenoise")


class LBLIGHT_OT_import_bake(bpy.types.Operator, ImportHelper):
    """Import an lblight bake (a model .vdb, a forest's manifest.json or forest.vdb) relit by the Sun
    lamp per object, or a relit volume (lblight relight) with its fixed sun"""

    bl_idname = "lblight.import_bake"
    bl_label = "Import lblight"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".vdb"
    filter_glob: StringProperty(default="*.vdb;*.json", options={"HIDDEN"})
    ambient: FloatProperty(name="Ambient", description="Ambient level (x B00): light from every direction",
                           default=0.0, min=0.0)
    sky: FloatProperty(name="Sky", description="Sky level: light from the upper hemisphere of each object's frame",
                       default=0.0, min=0.0)
    bake: StringProperty(name="Bake folder", subtype="DIR_PATH", default="",
                         description="For a relit volume whose bake (lblight_source) is not where it was: "
                                     "the bake folder holding its manifest.json (the materials)")
    setup_scene: BoolProperty(name="Set up scene", default=False, description=SETUP_DESCRIPTION)

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "ambient")
        layout.prop(self, "sky")
        layout.prop(self, "bake")
        layout.prop(self, "setup_scene")
        if self.setup_scene:
            col = layout.column(align=True)
            for line in ("Changes: engine Cycles (CPU),", "max and volume bounces 0,", "world strength 0,",
                         "film transparent, view Standard,", "denoising off without OIDN"):
                col.label(text=line)

    def execute(self, context):
        try:
            obj = import_bake(self.filepath, ambient=self.ambient, sky=self.sky, bake=self.bake or None,
                              scene=context.scene, collection=context.collection)
        except InputError as e:
            self.report({"ERROR"}, f"lblight: {e}")
            return {"CANCELLED"}
        except Exception as e:  # anything else is a bug, but the user gets a message, not a traceback
            self.report({"ERROR"}, f"lblight: {self.filepath}: import failed ({type(e).__name__}: {e})")
            return {"CANCELLED"}
        if self.setup_scene:
            configure_cycles(context.scene, context.scene.cycles.samples)
        for o in context.view_layer.objects:
            o.select_set(False)
        if obj.name in context.view_layer.objects:
            obj.select_set(True)
            context.view_layer.objects.active = obj
        what = obj.active_material.get("lblight_grids") if obj.type == "VOLUME" and obj.active_material else None
        self.report({"INFO"}, f"lblight: imported {obj.name}" + (f" ({what})" if what else ""))
        return {"FINISHED"}


class LBLIGHT_PT_object(bpy.types.Panel):
    bl_label = "lblight"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        o = context.object
        return o is not None and ("lblight_forest" in o or _lb_volume(o) is not None or _instanced_volume(o) is not None)

    def draw(self, context):
        layout, o = self.layout, context.object
        inner = _lb_volume(o) or _instanced_volume(o)
        if inner is not None and lbmaterial.kind(inner.active_material) == "static":
            box = layout.box()
            box.label(text="Static light: a Sun lamp does not change it", icon="INFO")
            box.label(text=str(inner.get("lblight_static", "")))
            if "lblight_note" in inner:
                box.label(text=str(inner["lblight_note"]), icon="ERROR")
            return
        for key, text in (("lblight_ambient", "Ambient"), ("lblight_sky", "Sky"),
                          ("lblight_sun", "Sun lamp (empty: the first)")):
            owner = o
            while owner is not None and key not in owner:
                owner = owner.parent
            if owner is not None:
                layout.prop(owner, f'["{key}"]', text=text + ("" if owner == o else f" ({owner.name})"))
        if inner is None:
            layout.label(text="Forest root: its instances are lit each in its own frame")
            return
        lamp = _sun_lamp(context.scene, _setting(o, "lblight_sun", "", inner))
        if lamp is None:
            layout.label(text="No Sun lamp: ambient and sky only", icon="ERROR")
        else:
            frame = next((f for h, v, f in lit_objects(context.scene) if h == o), o.matrix_world)
            toward, local, _ = sun_in_frame(lamp, frame)
            e, a = _elevation_azimuth(toward)
            layout.label(text=f"{lamp.name}: elevation {e:.1f}, azimuth {a:.1f} (world)")
            if local is not None:
                e, a = _elevation_azimuth(local)
                layout.label(text=f"in this object's frame: elevation {e:.1f}, azimuth {a:.1f}")
        if o.get("lblight_below"):
            layout.label(text="Sun below this object's horizon: sky and ambient only", icon="INFO")
        if "lblight_missing" in o:
            layout.label(text="Left out by the bake: " + o["lblight_missing"], icon="ERROR")


def _menu(self, context):
    self.layout.operator(LBLIGHT_OT_import_bake.bl_idname, text="lblight bake (.vdb, manifest.json)")


_HANDLERS = ("depsgraph_update_post", "frame_change_post", "render_pre")


def register():
    bpy.utils.register_class(LBLIGHT_OT_import_bake)
    bpy.utils.register_class(LBLIGHT_PT_object)
    bpy.types.TOPBAR_MT_file_import.append(_menu)
    for name in _HANDLERS:
        h = getattr(bpy.app.handlers, name)
        if _follow_sun not in h:
            h.append(_follow_sun)


def unregister():
    for name in _HANDLERS:
        h = getattr(bpy.app.handlers, name)
        if _follow_sun in h:
            h.remove(_follow_sun)
    bpy.types.TOPBAR_MT_file_import.remove(_menu)
    bpy.utils.unregister_class(LBLIGHT_PT_object)
    bpy.utils.unregister_class(LBLIGHT_OT_import_bake)
