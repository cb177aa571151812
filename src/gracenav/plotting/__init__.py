"""Figures. Every function imports matplotlib lazily and draws with the Agg backend."""
