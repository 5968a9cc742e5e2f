"""The machine-element library of multipole.

Importing this package registers its element types in the kernel's catalogue
(``multipole.catalogue``); it uses only the kernel's public API.
"""
from . import basic  # noqa: F401  (registers the basic elements)
