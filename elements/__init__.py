"""The machine-element library of multipole.

Importing this package registers its element types in the kernel's catalogue
(``multipole.catalogue``); it uses only the kernel's public API.
"""
from . import basic, gears, motor, piezo, planetary  # noqa: F401  (each registers its elements)
