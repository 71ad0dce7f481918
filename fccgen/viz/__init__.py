"""Pictures of a model and its motion: time-history plots of result columns
(:mod:`fccgen.viz.plot`, matplotlib) and a self-contained 3-D animation page
(:mod:`fccgen.viz.animate`, plotly). Both libraries are imported only when used."""
