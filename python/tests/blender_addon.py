"""Runs inside Blender (`blender -b --factory-startup --python-exit-code 1 --python THIS --
ZIP WORK`): installs the add-on from its zip, runs "Add ipfn texture" on the shipped honeycomb
and on the map-set model WORK/maps.ipfn, and checks the images' pixels against `ipfn synth`'s
arrays (WORK/honeycomb.npy, WORK/maps-NAME.npy, painted by test_blender.py) and the material's
node links; then "Re-seed" and "Repaint at another size". Any failed check raises, and Blender
exits with 1.
"""

import os
import sys

import bpy
import numpy as np

zip_path, work = sys.argv[sys.argv.index("--") + 1:][:2]

bpy.ops.preferences.addon_install(filepath=zip_path)
bpy.ops.preferences.addon_enable(module="ipfn_blender")
import ipfn_blender  # noqa: E402  (installed just above)


def expected_pixels(path):
    return ipfn_blender.to_pixels(np.load(path))


def pixels(image):
    values = np.empty(len(image.pixels), dtype=np.float32)
    image.pixels.foreach_get(values)
    return values


def linked(socket):
    """The node feeding `socket` (None where nothing is linked)."""
    return socket.links[0].from_node if socket.is_linked else None


def fresh_object(name):
    bpy.ops.mesh.primitive_plane_add()
    obj = bpy.context.active_object
    obj.name = name
    return obj


# The shipped honeycomb: one sRGB image into Base Color.
obj = fresh_object("honeycomb")
assert bpy.ops.ipfn.add_texture(model="", width=64, height=48, seed=2, tile=False) == {"FINISHED"}
material = obj.active_material
bsdf = next(n for n in material.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
texture = linked(bsdf.inputs["Base Color"])
assert texture is not None and texture.type == "TEX_IMAGE", "Base Color is linked to the image"
image = texture.image
assert tuple(image.size) == (64, 48) and image.is_float
assert image.colorspace_settings.name == "sRGB"
np.testing.assert_allclose(pixels(image), expected_pixels(os.path.join(work, "honeycomb.npy")),
                           atol=1e-6)
print("honeycomb: pixels and links checked")

# Re-seed and repaint at another size, on the active node.
material.node_tree.nodes.active = texture
override = {"object": obj, "active_object": obj}
with bpy.context.temp_override(**override):
    assert bpy.ops.ipfn.reseed() == {"FINISHED"}
assert image["ipfn_seed"] == 3
np.testing.assert_allclose(pixels(image), expected_pixels(os.path.join(work, "honeycomb-s3.npy")),
                           atol=1e-6)
with bpy.context.temp_override(**override):
    assert bpy.ops.ipfn.resize(width=32, height=40) == {"FINISHED"}
assert tuple(image.size) == (32, 40)
np.testing.assert_allclose(pixels(image), expected_pixels(os.path.join(work, "honeycomb-32x40.npy")),
                           atol=1e-6)
lines = ipfn_blender.describe(image)
assert lines[0].startswith("image, 3 channels"), lines
print("re-seed and resize checked:", lines)

# A map set: colour, normal, roughness and height, each where a material wants it.
obj = fresh_object("maps")
model = os.path.join(work, "maps.ipfn")
assert bpy.ops.ipfn.add_texture(model=model, width=40, height=32, seed=1, tile=False) == {"FINISHED"}
material = obj.active_material
nodes = material.node_tree.nodes
bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
output = next(n for n in nodes if n.type == "OUTPUT_MATERIAL")
by_map = {}
for node in nodes:
    if node.type == "TEX_IMAGE" and node.image is not None:
        by_map[node.image["ipfn_map"]] = node
assert sorted(by_map) == ["color", "height", "normal", "roughness"], sorted(by_map)
assert linked(bsdf.inputs["Base Color"]) == by_map["color"]
assert linked(bsdf.inputs["Roughness"]) == by_map["roughness"]
normal_map = linked(bsdf.inputs["Normal"])
assert normal_map.type == "NORMAL_MAP" and linked(normal_map.inputs["Color"]) == by_map["normal"]
displacement = linked(output.inputs["Displacement"])
assert displacement.type == "DISPLACEMENT"
assert linked(displacement.inputs["Height"]) == by_map["height"]
assert by_map["normal"].image.colorspace_settings.name == "Non-Color"
for name, node in by_map.items():
    expected = expected_pixels(os.path.join(work, f"maps-{name}.npy"))
    np.testing.assert_allclose(pixels(node.image), expected, atol=1e-6)
print("map set: pixels and links checked")

# A picture of the add-on's work: a plane with the honeycomb material, rendered.
if len(sys.argv) > sys.argv.index("--") + 3:
    render_to = sys.argv[sys.argv.index("--") + 3]
    scene = bpy.context.scene
    for o in list(scene.objects):
        o.hide_render = o.name != "honeycomb"
    honeycomb = scene.objects["honeycomb"]
    honeycomb.hide_render = False
    # Repainted big enough to read in the picture.
    with bpy.context.temp_override(object=honeycomb, active_object=honeycomb):
        assert bpy.ops.ipfn.resize(width=512, height=512) == {"FINISHED"}
    bpy.ops.object.camera_add(location=(0, -1.6, 1.2), rotation=(0.93, 0, 0))
    scene.camera = bpy.context.active_object
    bpy.ops.object.light_add(type="SUN", rotation=(0.6, 0.2, 0.4))
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 32
    scene.cycles.use_denoising = False  # Debian's Blender is built without OpenImageDenoise
    scene.render.resolution_x, scene.render.resolution_y = 480, 320
    scene.render.filepath = render_to
    bpy.ops.render.render(write_still=True)
    print("rendered", render_to)

print("ipfn add-on: all checks passed")
