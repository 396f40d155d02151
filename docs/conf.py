"""Sphinx configuration of the pbvs_pin documentation (built by ``python docs/build.py``)."""

project = "pbvs_pin"
author = "the pbvs_pin developers"
copyright = "the pbvs_pin developers"

extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax"]

napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True  # dataclass "Attributes:" as fields, not duplicate attribute entries
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": True}

smartquotes = False  # keys and values read as typed
html_theme = "alabaster"
html_static_path: list[str] = []
exclude_patterns = ["_build"]
