"""The figures of this package: a matplotlib ``Figure`` on its own Agg canvas.

No figure is made through pyplot and no backend is chosen: a user's interactive backend
and pyplot's figure list are left alone, and nothing needs closing.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["agg_figure"]


def agg_figure(**kwargs: Any) -> Figure:
    """A new ``Figure(**kwargs)`` drawn by an Agg canvas (``fig.canvas.draw()`` renders
    into memory; ``fig.savefig`` writes any format matplotlib knows)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig
