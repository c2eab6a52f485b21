"""The Blender add-on (`addon.py`, installed in Blender as `ipfn_blender`) and its installer:
`python -m ipfn.blender [ZIP]` writes the zip to install from Blender's Preferences. Importing
this package outside Blender imports nothing of Blender's.
"""
