"""Figures. Every function imports matplotlib lazily and draws on its own ``Figure`` with
an Agg canvas: pyplot is not used and the matplotlib backend is never switched."""
