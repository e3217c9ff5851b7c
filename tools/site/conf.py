"""Sphinx configuration of the course site (tools/build_site.py runs sphinx-build with it).

Sphinx + MyST-NB + the book theme: MyST-NB reads the executed notebooks as they are (no execution
here: `make course` executes them first, `make site` takes the committed ones, executed in CI mode);
Sphinx gives the navigation, the search (a local index: works offline) and cross-page links; MathJax
2.7 is served from the site itself (_static/mathjax, copied by build_site.py), never from a CDN.
"""

project = "Data-driven human motion synthesis"
author = "course_lib"
copyright = "the course's authors"  # noqa: A001  (Sphinx's name)
extensions = ["myst_nb"]
nb_execution_mode = "off"  # the notebooks arrive executed
nb_ipywidgets_js = {}  # no require.js / widget manager from a CDN (progress bars show as text)
nb_output_stderr = "remove-warn"  # keep stderr out of the pages, but say when a cell wrote some
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3
myst_update_mathjax = False  # MyST would write a MathJax 3 config (window.MathJax = ...) that stops MathJax 2
exclude_patterns = ["_build", "**.ipynb_checkpoints"]
suppress_warnings = ["myst.header", "mystnb.unknown_mime_type"]

html_theme = "sphinx_book_theme"
html_title = "Human motion synthesis"
html_theme_options = {
    "show_toc_level": 2,
    "home_page_in_toc": True,
    "use_download_button": True,
    "navigation_with_keys": False,
}
html_static_path = ["_static"]  # course.css: MathJax 2 inside the pydata theme (see the file)
html_css_files = ["course.css"]
html_last_updated_fmt = None
html_copy_source = True  # _sources/: the download button offers each lesson as .ipynb

# MathJax 2.7 from the site's own copy (site/_static/mathjax); STIX-Web is the only web font it ships
mathjax_path = "mathjax/MathJax.js?config=TeX-AMS-MML_HTMLorMML-full,Safe"
mathjax2_config = {
    "HTML-CSS": {"availableFonts": [], "preferredFont": None, "webFont": "STIX-Web", "imageFont": None},
    # MyST marks each page's section tex2jax_ignore: typeset only its math elements (and the outputs' HTML)
    "tex2jax": {"inlineMath": [["\\(", "\\)"]], "displayMath": [["\\[", "\\]"]], "processEscapes": True,
                "processClass": "math|tex2jax_process|mathjax_process|output_area"},
}
