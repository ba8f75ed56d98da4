"""The names a user picks a simulated scene by: its world and the scale of furniture models. Free of imports, so
that the command line offers them without loading the simulator."""

WORLDS = {"kitchen": "a seeded kitchen around the target furniture (the default)",
          "box": "one cabinet on a pedestal in empty space (the ablation)"}
SCALES = {"real": "sized as a real piece of its category (the default)",
          "native": "the model's own units as metres, as the paper and RGBManip load it"}
