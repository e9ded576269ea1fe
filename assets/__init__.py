"""The MJCF models shipped with robofdi (package data; read them through ``robofdi.assets_dir()``)."""
