"""The machine-element library of multipole.

Importing this package registers its element types in the kernel's catalogue
(``multipole.catalogue``); it uses only the kernel's public API.

Each type is declared once, with :func:`multipole.element` on its builder: the ports, the
parameters (unit, default, rules; the builder takes exactly these, in this order, and declares no
defaults of its own) and the quantities (``"unit: meaning"``; the builder's ``Quantity`` objects
carry only their expression, or the unit they were built in when it depends on the domain).
``tests/test_catalogue.py`` builds every type and fails when a declaration and the build differ.
"""
from . import basic, belt, belt_checks, belt_contour, belt_friction, belt_planar, belt_planar_curve, belt_spans, gears, linkage, linkage_guides, linkage_slide, motor, piezo, planetary  # noqa: F401  (each registers its elements)
