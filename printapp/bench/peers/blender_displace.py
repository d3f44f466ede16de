"""The talk's Blender workflow, headless: height map -> subdivided grid -> Displace -> STL.

Run by `printapp bench mesh` as the peer:
    blender -b --factory-startup --python-exit-code 1 --python printapp/bench/peers/blender_displace.py -- \
        MAP.png N OUT.stl WIDTH_MM DEPTH_MM
An N x N-quad grid of WIDTH_MM, displaced by DEPTH_MM for white, read as Non-Color data
(Blender would otherwise bend the heights by the sRGB curve). The result is an open
sheet, as in the talk: the printable slab that printapp makes has walls and a floor.
"""

import sys

import bpy

map_path, n, out_path = sys.argv[sys.argv.index("--") + 1 :][:3]
width_mm, depth_mm = (float(v) for v in sys.argv[sys.argv.index("--") + 4 :][:2])
n = int(n)

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_grid_add(x_subdivisions=n, y_subdivisions=n, size=1.0, calc_uvs=True)
grid = bpy.context.active_object
image = bpy.data.images.load(map_path)
image.colorspace_settings.name = "Non-Color"
texture = bpy.data.textures.new("height", type="IMAGE")
texture.image = image
texture.extension = "EXTEND"
displace = grid.modifiers.new("Displace", type="DISPLACE")
displace.texture = texture
displace.texture_coords = "UV"
displace.strength = depth_mm / width_mm  # the grid is one unit wide; scaled on export
displace.mid_level = 0.0
bpy.ops.object.modifier_apply(modifier=displace.name)
bpy.ops.export_mesh.stl(filepath=out_path, ascii=False, use_mesh_modifiers=True, global_scale=width_mm)
print("printapp-peer: done")
