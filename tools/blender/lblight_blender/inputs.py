"""What a path given to the importer is, checked before anything is created (no bpy here): a model
of an lblight bake, a relit volume (`lblight relight`, a fixed sun), or a whole forest bake. Every
refusal is an InputError whose message names the file and says why, for the operator's report."""
import json
import os

from . import vdbinfo


class InputError(ValueError):
    pass


def _is_base_grid(name):
    return len(name) == 3 and name[0] == "B" and name[1:].isdigit()


def _manifest(folder, required_by=None):
    """(path, manifest) of the manifest.json in folder, or (path, None) when there is none."""
    path = os.path.join(folder, "manifest.json")
    if not os.path.exists(path):
        return path, None
    try:
        with open(path) as f:
            manifest = json.load(f)
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: cannot read it as JSON ({e})")
    if not isinstance(manifest, dict) or not isinstance(manifest.get("models"), list) or "lblight_version" not in manifest:
        raise InputError(f"{path}: not an lblight manifest (no lblight_version and models)")
    return path, manifest


def _vdb(path):
    try:
        return vdbinfo.read(path)
    except vdbinfo.VdbError as e:
        raise InputError(f"{path}: {e}")
    except OSError as e:
        raise InputError(f"{path}: cannot read it ({e.strerror or e})")


def _materials(entry, manifest_path):
    m = entry.get("materials")
    if not isinstance(m, dict) or not isinstance(m.get("medium"), dict):
        raise InputError(f"{manifest_path}: model '{entry.get('name')}' names no materials (materials.medium)")
    for key in ("medium", "wood"):
        if key in m and not all(isinstance(m[key].get(k), list) and len(m[key][k]) == 3 for k in ("sigma_a", "sigma_s")):
            raise InputError(f"{manifest_path}: model '{entry.get('name')}' material {key} lacks sigma_a/sigma_s per channel")
    return m["medium"], m.get("wood", m["medium"])


def _voxel(entry, manifest_path):
    try:
        h = [float(x) for x in entry["lattice"]["voxel_size"]]
        assert len(h) == 3 and min(h) > 0
        return h
    except (KeyError, TypeError, ValueError, AssertionError):
        raise InputError(f"{manifest_path}: model '{entry.get('name')}' has no lattice.voxel_size")


def _model_entries(manifest):
    return [m for m in manifest["models"] if isinstance(m, dict) and isinstance(m.get("file"), str)
            and m.get("role", "model") == "model"]


def _model_plan(folder, manifest_path, entry):
    vdb = os.path.join(folder, entry["file"])
    if not os.path.exists(vdb):
        raise InputError(f"{vdb}: missing (model '{entry['name']}' of {manifest_path})")
    info = _vdb(vdb)
    names = [g["name"] for g in info["grids"]]
    stated = info["metadata"].get("lblight_model")
    if stated is not None and stated != entry["name"]:
        raise InputError(f"{vdb}: its metadata names model '{stated}', {manifest_path} '{entry['name']}'")
    medium, wood = _materials(entry, manifest_path)
    base = sorted(n for n in names if _is_base_grid(n))
    plan = {"vdb": vdb, "name": entry["name"], "medium": medium, "wood": wood,
            "voxel": _voxel(entry, manifest_path), "grids": names}
    if base:
        plan.update(kind="model", base=base)
    elif "light" in names:
        plan.update(kind="static", sun=None)  # a static bake: its light for the scene's sun
    else:
        raise InputError(f"{vdb}: no base solutions (B00..B18) and no light grid; it holds {', '.join(n or '(unnamed)' for n in names) or 'no grids'}")
    if "density" not in names:
        raise InputError(f"{vdb}: no density grid")
    return plan


def _choose_model(manifest, manifest_path, model):
    entries = _model_entries(manifest)
    if model:
        entries = [m for m in entries if m.get("name") == model]
    if len(entries) != 1:
        names = ", ".join(str(m.get("name")) for m in _model_entries(manifest))
        raise InputError(f"{manifest_path}: choose one model of the bake ({names})" if not model else
                         f"{manifest_path}: no model '{model}' (it has {names})")
    return entries[0]


def _forest_plan(folder, manifest_path, manifest):
    forest = manifest["forest"]
    cols = forest.get("instance_columns")
    rows = forest.get("instances")
    need = ["model", "x", "y", "z", "yaw_degrees", "scale"]
    if not isinstance(cols, list) or any(c not in cols for c in need) or not isinstance(rows, list):
        raise InputError(f"{manifest_path}: its forest section lacks instance_columns ({', '.join(need)}) or instances")
    at = {c: cols.index(c) for c in need}
    entries = {m.get("name"): m for m in _model_entries(manifest)}
    instances, models = [], {}
    for i, row in enumerate(rows):
        try:
            name = row[at["model"]]
            inst = {"model": name, "position": [float(row[at[c]]) for c in ("x", "y", "z")],
                    "yaw_degrees": float(row[at["yaw_degrees"]]), "scale": float(row[at["scale"]])}
        except (TypeError, ValueError, IndexError):
            raise InputError(f"{manifest_path}: forest instance {i} is malformed ({row!r})")
        if name not in entries:
            raise InputError(f"{manifest_path}: forest instance {i} names model '{name}', which the bake does not hold")
        if name not in models:
            models[name] = _model_plan(folder, manifest_path, entries[name])
            if models[name]["kind"] != "model":
                raise InputError(f"{models[name]['vdb']}: a forest model without base solutions")
        instances.append(inst)
    if not instances:
        raise InputError(f"{manifest_path}: the forest has no instances")
    return {"kind": "forest", "name": manifest.get("scene", {}).get("name") or os.path.basename(folder) or "forest",
            "folder": folder, "manifest": manifest_path, "models": models, "instances": instances}


def _self_described(path, info):
    """(medium, wood) from the density grid's lblight_material_* metadata, or None without it."""
    density = next((g for g in info["grids"] if g["name"] == "density"), None)
    meta = density.get("metadata", {}) if density else {}
    if not isinstance(meta.get("lblight_material_medium"), str):
        return None
    try:
        medium = json.loads(meta["lblight_material_medium"])
        wood = json.loads(meta["lblight_material_wood"]) if isinstance(meta.get("lblight_material_wood"), str) else medium
    except ValueError as e:
        raise InputError(f"{path}: its density's material metadata is not valid JSON ({e})")
    entry = {"name": os.path.basename(path), "materials": {"medium": medium, "wood": wood}}
    return _materials(entry, path)


def _relit_plan(path, info, bake):
    meta = info["metadata"]
    names = [g["name"] for g in info["grids"]]
    if "density" not in names:
        raise InputError(f"{path}: a light grid without density; not a volume `lblight relight` wrote")
    source = meta.get("lblight_source") if isinstance(meta.get("lblight_source"), str) else None
    where = bake
    described = _self_described(path, info)
    if not where and described:  # the file says what it is made of (docs/output-format.md)
        medium, wood = described
        sun = {k: meta.get("lblight_" + k) for k in ("sun_elevation", "sun_azimuth", "intensity", "ambient", "sky")}
        return {"kind": "static", "vdb": path, "name": os.path.splitext(os.path.basename(path))[0], "medium": medium,
                "wood": wood, "voxel": None, "grids": names, "sun": sun, "source": path, "note": None}
    if not where:
        if source is None:
            raise InputError(f"{path}: a light + density volume without lblight metadata (stripped?), so its "
                             "bake's materials are unknown; name the bake folder (Bake folder, or bake=) to import it")
        tries = [source] if os.path.isabs(source) else [os.path.join(os.path.dirname(path), source), os.path.abspath(source),
                                                         os.path.join(os.path.dirname(path), os.path.basename(source))]
        where = next((t for t in tries if os.path.exists(t)), None)
        if where is None:
            raise InputError(f"{path}: its bake ({source}, lblight_source) is not found; name the bake folder "
                             "(Bake folder, or bake=) to import it")
    where = os.path.abspath(where)
    folder = where if os.path.isdir(where) else os.path.dirname(where)
    manifest_path, manifest = _manifest(folder)
    if manifest is None:
        raise InputError(f"{path}: its bake {where} has no manifest.json (the materials are there)")
    entries = _model_entries(manifest)
    if where.endswith(".vdb") and os.path.basename(where) in [m["file"] for m in entries]:
        entries = [m for m in entries if m["file"] == os.path.basename(where)]
    elif "forest" not in manifest and len(entries) > 1:
        stated = meta.get("lblight_model")
        entries = [m for m in entries if m.get("name") == stated] or entries[:1]
    if not entries:
        raise InputError(f"{path}: its bake's {manifest_path} holds no model")
    medium, wood = _materials(entries[0], manifest_path)
    differ = [m["name"] for m in entries[1:] if _materials(m, manifest_path) != (medium, wood)]
    sun = {k: meta.get("lblight_" + k) for k in ("sun_elevation", "sun_azimuth", "intensity", "ambient", "sky")}
    notes = []
    if differ:
        notes.append(f"materials of {entries[0]['name']} used for all (also {', '.join(differ)}, which differ)")
    if "brown" not in names and any(wood.get(k) != medium.get(k) for k in ("sigma_a", "sigma_s")):
        # `lblight relight` of one model writes light and density only: its wood cannot be told apart.
        notes.append(f"no brown grid: wood drawn as {medium.get('name', 'the medium')}")
    return {"kind": "static", "vdb": path, "name": os.path.splitext(os.path.basename(path))[0], "medium": medium,
            "wood": wood, "voxel": None, "grids": names, "sun": sun, "source": where,
            "note": "; ".join(notes) or None}


def plan(path, model=None, bake=None, forest=None):
    """What importing `path` (absolute) means. forest: True imports the forest of a forest bake from
    any of its files, False one model, None (auto) the forest for its manifest.json, its folder or
    forest.vdb and the model for a model .vdb."""
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file or folder")
    if os.path.isdir(path) or os.path.basename(path) == "manifest.json":
        folder = path if os.path.isdir(path) else os.path.dirname(path)
        manifest_path, manifest = _manifest(folder)
        if manifest is None:
            raise InputError(f"{folder}: no manifest.json; not an lblight bake folder")
        if "forest" in manifest and forest is not False and not model:
            return _forest_plan(folder, manifest_path, manifest)
        return _model_plan(folder, manifest_path, _choose_model(manifest, manifest_path, model))
    info = _vdb(path)
    names = [g["name"] for g in info["grids"]]
    meta = info["metadata"]
    if "light" in names and not any(_is_base_grid(n) for n in names) and (
            "lblight_source" in meta or not os.path.exists(os.path.join(os.path.dirname(path), "manifest.json"))):
        return _relit_plan(path, info, bake)
    folder = os.path.dirname(path)
    manifest_path, manifest = _manifest(folder)
    if manifest is None:
        lblight_meta = sorted(k for k in meta if k.startswith("lblight_"))
        if any(_is_base_grid(n) for n in names):
            if lblight_meta:
                raise InputError(f"{path}: a model of an lblight bake without its manifest.json beside it (it holds the "
                                 "materials and voxel size): import it from its bake folder")
            raise InputError(f"{path}: base-solution grids but no lblight metadata and no manifest.json beside it: "
                             "not an lblight bake, or its metadata was stripped")
        raise InputError(f"{path}: not an lblight bake: no manifest.json beside it, no lblight metadata, no B00..B18 or "
                         f"light grid (it holds {', '.join(n or '(unnamed)' for n in names) or 'no grids'})")
    entry = next((m for m in manifest["models"] if isinstance(m, dict) and m.get("file") == os.path.basename(path)), None)
    if entry is None:
        raise InputError(f"{path}: not a file of the bake in {manifest_path}")
    role = entry.get("role", "model")
    if role == "forest" or (forest and "forest" in manifest):
        if "forest" not in manifest:
            raise InputError(f"{manifest_path}: no forest section")
        return _forest_plan(folder, manifest_path, manifest)
    if role != "model":
        raise InputError(f"{path}: a coarse helper grid of the forest ({role}); import the forest (manifest.json or "
                         "forest.vdb) or a model .vdb")
    if model and model != entry["name"]:
        raise InputError(f"{path}: holds model '{entry['name']}', not '{model}'")
    return _model_plan(folder, manifest_path, entry)
