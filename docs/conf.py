"""Sphinx configuration of the pbvs_pin documentation (built by ``python docs/build.py``)."""

project = "pbvs_pin"
author = "the pbvs_pin developers"
copyright = "the pbvs_pin developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax 3 from the package, copied into _static: no CDN
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
myst_heading_anchors = 3  # "#some-heading" links inside and between Markdown pages

napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True  # dataclass "Attributes:" as fields, not duplicate attribute entries
autodoc_member_order = "bysource"
autodoc_typehints = "description"
# ``npt.ArrayLike`` shows as ArrayLike, not as its expansion (a page-long Union)
autodoc_type_aliases = {
    "npt.ArrayLike": "numpy.typing.ArrayLike",
    "ArrayLike": "numpy.typing.ArrayLike",
}
autodoc_default_options = {"members": True, "show-inheritance": True}

smartquotes = False  # keys and values read as typed
html_theme = "furo"  # maintained; its assets ship with the package, so the build is offline
html_title = "pbvs_pin"
html_static_path = ["_static"]
exclude_patterns = ["_build", "README.md"]
