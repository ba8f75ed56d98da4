"""PartNet-Mobility objects (the furniture models the paper and RGBManip measure on) as `Furniture`."""

from sim_fallback.partnet.errors import PartNetError
from sim_fallback.partnet.layout import find_object, object_folders
from sim_fallback.partnet.listing import ObjectEntry, list_objects, usable
from sim_fallback.partnet.loader import SCALE_RULES, load_partnet

__all__ = ["PartNetError", "ObjectEntry", "SCALE_RULES", "find_object", "list_objects", "load_partnet",
           "object_folders", "usable"]
