"""ipfn for Blender: paint an ipfn model into a float image and wire it into the material.

Installed as the add-on `ipfn_blender` (a zip that `python -m ipfn.blender` writes, with this
package inside it). In the Shader editor: Add > ipfn texture, or the sidebar's ipfn tab:
- "Add ipfn texture": a model file or run folder (none: the shipped honeycomb), size, seed,
  zoom, tile; paints into float image datablocks and links them into the active material (a
  map set: base colour, a Normal Map node, roughness, displacement);
- "Re-seed" and "Repaint at another size" on the active node's ipfn image;
- a panel with the model's kind, training iteration and scores.
"""

import os
import sys

bl_info = {
    "name": "ipfn texture",
    "author": "ipfn",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Shader Editor > Add > ipfn texture; Sidebar > ipfn",
    "description": "Seamless textures painted by an Implicit Periodic Field Network",
    "category": "Material",
}

# The zip carries the ipfn package beside this file (vendor/ipfn).
_VENDOR = os.path.join(os.path.dirname(__file__), "vendor")
if os.path.isdir(_VENDOR) and _VENDOR not in sys.path:
    sys.path.insert(0, _VENDOR)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import ipfn  # noqa: E402

# Custom properties an ipfn image keeps, so it can be repainted.
_PROPS = ("ipfn_model", "ipfn_map", "ipfn_role", "ipfn_seed", "ipfn_zoom", "ipfn_tile")

# Where a map goes in a Principled BSDF material, by its role (ipfn reads roles from the maps'
# file names when it trains: Model.map_roles).
_INPUTS = {"color": "Base Color", "roughness": "Roughness", "metalness": "Metallic"}


def to_pixels(array):
    """An ipfn array `[H, W, C]` in [-1, 1] as Blender's flat RGBA floats (rows bottom up)."""
    h, w, c = array.shape
    unit = np.clip((array + 1.0) * 0.5, 0.0, 1.0)
    rgba = np.ones((h, w, 4), dtype=np.float32)
    if c >= 3:
        rgba[:, :, :3] = unit[:, :, :3]
    else:
        rgba[:, :, :3] = unit[:, :, :1]
    if c in (2, 4):
        rgba[:, :, 3] = unit[:, :, -1]
    return rgba[::-1].reshape(-1)


def paint_images(model_path, width, height, seed, zoom, tile):
    """Paints the model into one float image per map: `{map name or "": image}`."""
    model = ipfn.load(model_path or None)
    painted = model.paint(width, height, seed=seed, zoom=zoom, tile=tile, device="cpu")
    arrays = painted if isinstance(painted, dict) else {"": painted}
    stem = os.path.splitext(os.path.basename(model_path))[0] if model_path else "honeycomb"
    roles = dict(zip(model.map_names, model.map_roles))
    images = {}
    for name, array in arrays.items():
        label = f"ipfn {stem} {name}".strip() + f" s{seed}"
        image = bpy.data.images.new(label, width, height, alpha=True, float_buffer=True)
        image["ipfn_role"] = roles.get(name) or ("color" if not name else "")
        write_image(image, array)
        image["ipfn_model"] = model_path or ""
        image["ipfn_map"] = name
        image["ipfn_seed"] = seed
        image["ipfn_zoom"] = zoom
        image["ipfn_tile"] = tile
        images[name] = image
    return model, images


def write_image(image, array):
    """Fills `image` with `array`; colour maps are sRGB-encoded, other maps data."""
    color = image["ipfn_role"] == "color"
    image.colorspace_settings.name = "sRGB" if color else "Non-Color"
    image.pixels.foreach_set(to_pixels(array))
    image.update()


def wire(material, images):
    """Links the images into `material`'s Principled BSDF (creating the nodes it needs)."""
    material.use_nodes = True
    tree = material.node_tree
    nodes, links = tree.nodes, tree.links
    bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
    if bsdf is None:
        bsdf = nodes.new("ShaderNodeBsdfPrincipled")
    output = next((n for n in nodes if n.type == "OUTPUT_MATERIAL"), None)
    if output is None:
        output = nodes.new("ShaderNodeOutputMaterial")
        links.new(bsdf.outputs["BSDF"], output.inputs["Surface"])
    made = []
    for i, (name, image) in enumerate(images.items()):
        node = nodes.new("ShaderNodeTexImage")
        node.image = image
        node.label = image.name
        node.location = (bsdf.location.x - 600, bsdf.location.y - 280 * i)
        made.append(node)
        role = image["ipfn_role"]
        if role in _INPUTS:
            links.new(node.outputs["Color"], bsdf.inputs[_INPUTS[role]])
        elif role == "normal":
            normal = nodes.new("ShaderNodeNormalMap")
            normal.location = (node.location.x + 300, node.location.y)
            links.new(node.outputs["Color"], normal.inputs["Color"])
            links.new(normal.outputs["Normal"], bsdf.inputs["Normal"])
        elif role == "height":
            displacement = nodes.new("ShaderNodeDisplacement")
            displacement.location = (node.location.x + 300, node.location.y)
            links.new(node.outputs["Color"], displacement.inputs["Height"])
            links.new(displacement.outputs["Displacement"], output.inputs["Displacement"])
    if made:
        nodes.active = made[0]
    return made


def active_ipfn_image(context):
    """The image of the active Image Texture node, where ipfn painted it."""
    space = context.space_data
    tree = getattr(space, "edit_tree", None) if space else None
    if tree is None:
        material = getattr(context.object, "active_material", None) if context.object else None
        tree = material.node_tree if material and material.use_nodes else None
    node = tree.nodes.active if tree else None
    image = getattr(node, "image", None) if node else None
    return image if image is not None and "ipfn_seed" in image else None


def repaint(image, width, height, seed):
    """Paints `image`'s model again at `width` x `height` and `seed`, in place."""
    model = ipfn.load(image["ipfn_model"] or None)
    painted = model.paint(
        width, height, seed=seed, zoom=image["ipfn_zoom"], tile=bool(image["ipfn_tile"]),
        device="cpu",
    )
    name = image["ipfn_map"]
    array = painted[name] if isinstance(painted, dict) else painted
    if tuple(image.size) != (width, height):
        # A generated image (as `bpy.data.images.new` makes) takes its size from these; scale()
        # leaves its buffer as it was.
        if image.source == "GENERATED":
            image.generated_width, image.generated_height = width, height
        else:
            image.scale(width, height)
    write_image(image, array)
    image["ipfn_seed"] = seed


class IPFN_OT_add_texture(bpy.types.Operator):
    """Paint an ipfn model into float images and link them into the active material"""

    bl_idname = "ipfn.add_texture"
    bl_label = "Add ipfn texture"
    bl_options = {"REGISTER", "UNDO"}

    model: bpy.props.StringProperty(
        name="Model", subtype="FILE_PATH",
        description="A .ipfn file or a run folder; empty: the shipped honeycomb",
    )
    width: bpy.props.IntProperty(name="Width", default=1024, min=1, max=16384)
    height: bpy.props.IntProperty(name="Height", default=1024, min=1, max=16384)
    seed: bpy.props.IntProperty(name="Seed", default=0, min=0)
    zoom: bpy.props.FloatProperty(name="Zoom", default=1.0, min=0.01)
    tile: bpy.props.BoolProperty(name="Tile", default=True, description="Seamless tile")

    def execute(self, context):
        obj = context.object
        if obj is None:
            self.report({"ERROR"}, "select an object: the texture goes into its material")
            return {"CANCELLED"}
        material = obj.active_material
        if material is None:
            material = bpy.data.materials.new("ipfn")
            obj.data.materials.append(material)
        path = bpy.path.abspath(self.model) if self.model else ""
        try:
            model, images = paint_images(
                path, self.width, self.height, self.seed, self.zoom, self.tile
            )
        except ipfn.IpfnError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        wire(material, images)
        self.report({"INFO"}, f"painted {model.kind} ({', '.join(images) or 'image'})")
        return {"FINISHED"}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)


class IPFN_OT_reseed(bpy.types.Operator):
    """Paint the active ipfn image again with the next seed"""

    bl_idname = "ipfn.reseed"
    bl_label = "Re-seed"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        image = active_ipfn_image(context)
        if image is None:
            self.report({"ERROR"}, "make an ipfn image's node active")
            return {"CANCELLED"}
        repaint(image, image.size[0], image.size[1], int(image["ipfn_seed"]) + 1)
        return {"FINISHED"}


class IPFN_OT_resize(bpy.types.Operator):
    """Paint the active ipfn image again at another size (same seed)"""

    bl_idname = "ipfn.resize"
    bl_label = "Repaint at another size"
    bl_options = {"REGISTER", "UNDO"}

    width: bpy.props.IntProperty(name="Width", default=2048, min=1, max=16384)
    height: bpy.props.IntProperty(name="Height", default=2048, min=1, max=16384)

    def execute(self, context):
        image = active_ipfn_image(context)
        if image is None:
            self.report({"ERROR"}, "make an ipfn image's node active")
            return {"CANCELLED"}
        repaint(image, self.width, self.height, int(image["ipfn_seed"]))
        return {"FINISHED"}

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self)


class IPFN_PT_panel(bpy.types.Panel):
    """The active ipfn image's model: kind, training iteration, scores"""

    bl_label = "ipfn"
    bl_space_type = "NODE_EDITOR"
    bl_region_type = "UI"
    bl_category = "ipfn"

    def draw(self, context):
        layout = self.layout
        layout.operator(IPFN_OT_add_texture.bl_idname)
        image = active_ipfn_image(context)
        if image is None:
            layout.label(text="No ipfn image active")
            return
        for line in describe(image):
            layout.label(text=line)
        row = layout.row()
        row.operator(IPFN_OT_reseed.bl_idname)
        row.operator(IPFN_OT_resize.bl_idname)


def describe(image):
    """Lines about an ipfn image's model: kind, iteration, scores of its run."""
    path = image["ipfn_model"]
    model = ipfn.load(path or None)
    lines = [f"{model.kind}, {model.channels} channels", f"seed {image['ipfn_seed']}"]
    if model.iteration is not None:
        lines.append(f"trained {model.iteration} iterations")
    scores = run_scores(model.path)
    if scores:
        lines.append(scores)
    return lines


def run_scores(model_path):
    """The last scored checkpoint's SIFID and structure in the model's run folder."""
    if not model_path:
        return None
    metrics = os.path.join(os.path.dirname(os.fspath(model_path)), "metrics.csv")
    if not os.path.isfile(metrics):
        return None
    with open(metrics) as f:
        rows = [r.strip().split(",") for r in f if r.strip()]
    header, rows = rows[0], rows[1:]
    if "sifid" not in header:
        return None
    s, t = header.index("sifid"), header.index("structure") if "structure" in header else None
    scored = [r for r in rows if len(r) > s and r[s]]
    if not scored:
        return None
    last = scored[-1]
    text = f"SIFID {float(last[s]):.2f}"
    if t is not None and len(last) > t and last[t]:
        text += f", structure {float(last[t]):.3f}"
    return text + f" (iteration {last[0]})"


def menu(self, context):
    self.layout.operator(IPFN_OT_add_texture.bl_idname, text="ipfn texture")


_CLASSES = (IPFN_OT_add_texture, IPFN_OT_reseed, IPFN_OT_resize, IPFN_PT_panel)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.NODE_MT_add.append(menu)


def unregister():
    bpy.types.NODE_MT_add.remove(menu)
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
