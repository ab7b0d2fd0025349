"""lblight for Blender: import an lblight bake as a Volume object with a relighting material that
follows a Sun lamp (docs/blender.md). File > Import > lblight bake, or from Python:

    import lblight_blender
    obj = lblight_blender.import_bake("out/default/tree.vdb")       # or the bake folder + model=
    lblight_blender.configure_cycles(bpy.context.scene)

The material sums the base solutions the lamp's direction selects (32-face decomposition, as
`lblight sun-weights`), weighted by the lamp's strength, plus the object's `lblight_ambient` and
`lblight_sky` levels; a handler recomputes the grids and weights whenever the lamp moves."""

bl_info = {
    "name": "lblight bakes",
    "author": "lblight",
    "version": (1, 0, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > lblight bake; Object properties > lblight",
    "description": "Import lblight lattice-Boltzmann light bakes and relight them from a Sun lamp",
    "category": "Import-Export",
}

import json
import os

import bpy
from bpy.app.handlers import persistent
from bpy.props import FloatProperty, StringProperty
from bpy_extras.io_utils import ImportHelper
from mathutils import Vector

from . import material as lbmaterial
from . import relight


# A lamp's rotation is float32: sun weights below this are its rounding, not light.
LAMP_NEGLIGIBLE = 1e-5


def _manifest_for(path, model):
    """(model .vdb, the manifest's model entry) for a bake folder or one of its model .vdb files."""
    path = os.path.abspath(bpy.path.abspath(path))
    folder = path if os.path.isdir(path) else os.path.dirname(path)
    manifest_path = os.path.join(folder, "manifest.json")
    if not os.path.exists(manifest_path):
        raise ValueError(f"{path}: no manifest.json beside it; import a model .vdb of an lblight bake folder")
    with open(manifest_path) as f:
        manifest = json.load(f)
    entries = [m for m in manifest["models"] if isinstance(m.get("file"), str) and m.get("role", "model") == "model"]
    if os.path.isdir(path):
        if model:
            entries = [m for m in entries if m["name"] == model]
        if len(entries) != 1:
            names = ", ".join(m["name"] for m in manifest["models"] if isinstance(m.get("file"), str))
            raise ValueError(f"{path}: choose one model of the bake ({names})")
        entry = entries[0]
    else:
        entry = next((m for m in entries if m["file"] == os.path.basename(path)), None)
        if entry is None:
            raise ValueError(f"{path}: not a model of the bake in {manifest_path}")
    return os.path.join(folder, entry["file"]), entry


def _sun_lamp(scene, name):
    lamp = scene.objects.get(name) if name else None
    if lamp is not None and lamp.type == "LIGHT":
        return lamp
    return next((o for o in scene.objects if o.type == "LIGHT" and o.data.type == "SUN"), None)


def relight_object(obj, scene):
    """Sets obj's material weights for the scene's sun lamp; returns {grid: weight}."""
    mat = obj.active_material
    if mat is None or "lblight_grids" not in mat:
        return {}
    lamp = _sun_lamp(scene, obj.get("lblight_sun", ""))
    ambient, sky = float(obj.get("lblight_ambient", 0.0)), float(obj.get("lblight_sky", 0.0))
    if lamp is None:
        w = relight.weights((0, 0, 1), 0.0, ambient, sky)
    else:
        toward = lamp.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))  # a sun shines along its -Z
        w = relight.weights(tuple(toward), float(lamp.data.energy), ambient, sky, negligible=LAMP_NEGLIGIBLE)
    missing = lbmaterial.set_weights(mat, w)
    if missing and obj.get("lblight_missing", "") != ",".join(missing):
        obj["lblight_missing"] = ",".join(missing)
        print(f"lblight: {obj.name}: this sun needs {', '.join(missing)}, which the bake left out (its sun_range "
              "or instance_rotation excludes it); those weights are dropped")
    elif not missing and "lblight_missing" in obj:
        del obj["lblight_missing"]
    return w


@persistent
def _follow_sun(scene, depsgraph=None):
    for obj in scene.objects:
        if obj.type == "VOLUME" and "lblight_model" in obj:
            relight_object(obj, scene)


def import_bake(path, model=None, name=None, sun=None, ambient=0.0, sky=0.0):
    """Imports a model of an lblight bake (a model .vdb, or the bake folder and `model`) as a Volume
    object with the relighting material; returns the object."""
    vdb, entry = _manifest_for(path, model)
    vol = bpy.data.volumes.new(name or entry["name"])
    vol.filepath = vdb
    vol.render.precision = "FULL"  # light values are not fractions of 1: keep float32
    vol.render.clipping = 0.0
    vol.grids.load()
    grids = [g.name for g in vol.grids if g.name[:1] == "B" and g.name[1:].isdigit()]
    if not grids:
        raise ValueError(f"{vdb}: no base solutions (B00..B18); a static bake's 'light' grid needs no relighting")
    materials = entry.get("materials", {})
    if "medium" not in materials:
        raise ValueError(f"{vdb}: the manifest names no materials for model {entry['name']}")
    voxel = float(entry["lattice"]["voxel_size"][0])
    mat = lbmaterial.build(f"lblight {entry['name']}", grids, materials["medium"],
                           materials.get("wood", materials["medium"]), voxel)
    mat["lblight_grids"] = ",".join(sorted(grids))
    vol.materials.append(mat)
    obj = bpy.data.objects.new(name or entry["name"], vol)
    # Blender draws voxel (i, j, k) over the cell [i, i+1]^3 of index space; OpenVDB, Houdini and
    # lblight put its value at the point (i, j, k). Half a voxel back so the light sits where it
    # was solved (measured: without it a 160x120 picture of the default tree differs from lblight
    # render's by 20% pixel-wise, with it by 1%).
    obj.location = [-0.5 * float(h) for h in entry["lattice"]["voxel_size"]]
    bpy.context.scene.collection.objects.link(obj)
    obj["lblight_model"] = entry["name"]
    obj["lblight_sun"] = sun or ""
    obj["lblight_ambient"] = float(ambient)
    obj["lblight_sky"] = float(sky)
    relight_object(obj, bpy.context.scene)
    return obj


def configure_cycles(scene, samples=16):
    """Cycles settings under which the material is what `lblight render --term lb` computes: no
    volume bounces (the LB solution holds the multiple scattering), a black world, linear film,
    and the denoiser off where the build has none (Debian's: "Build without OpenImageDenoiser")."""
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


class LBLIGHT_OT_import_bake(bpy.types.Operator, ImportHelper):
    """Import a model of an lblight bake (its .vdb) with a material relit by the Sun lamp"""

    bl_idname = "lblight.import_bake"
    bl_label = "Import lblight bake"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".vdb"
    filter_glob: StringProperty(default="*.vdb", options={"HIDDEN"})
    ambient: FloatProperty(name="Ambient", description="Ambient level (x B00)", default=0.0, min=0.0)
    sky: FloatProperty(name="Sky", description="Sky level (upper hemisphere)", default=0.0, min=0.0)

    def execute(self, context):
        try:
            obj = import_bake(self.filepath, ambient=self.ambient, sky=self.sky)
        except (ValueError, KeyError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        if context.scene.render.engine == "CYCLES":
            configure_cycles(context.scene, context.scene.cycles.samples)
        self.report({"INFO"}, f"lblight: imported {obj.name} ({obj.active_material['lblight_grids']})")
        return {"FINISHED"}


class LBLIGHT_PT_object(bpy.types.Panel):
    bl_label = "lblight"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return context.object is not None and "lblight_model" in context.object

    def draw(self, context):
        layout, o = self.layout, context.object
        layout.prop(o, '["lblight_ambient"]', text="Ambient")
        layout.prop(o, '["lblight_sky"]', text="Sky")
        layout.prop(o, '["lblight_sun"]', text="Sun lamp (empty: the first)")
        if "lblight_missing" in o:
            layout.label(text="Left out by the bake: " + o["lblight_missing"], icon="ERROR")


def _menu(self, context):
    self.layout.operator(LBLIGHT_OT_import_bake.bl_idname, text="lblight bake (.vdb)")


def register():
    bpy.utils.register_class(LBLIGHT_OT_import_bake)
    bpy.utils.register_class(LBLIGHT_PT_object)
    bpy.types.TOPBAR_MT_file_import.append(_menu)
    for h in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.frame_change_post):
        if _follow_sun not in h:
            h.append(_follow_sun)


def unregister():
    for h in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.frame_change_post):
        if _follow_sun in h:
            h.remove(_follow_sun)
    bpy.types.TOPBAR_MT_file_import.remove(_menu)
    bpy.utils.unregister_class(LBLIGHT_PT_object)
    bpy.utils.unregister_class(LBLIGHT_OT_import_bake)
