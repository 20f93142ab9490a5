"""Matplotlib figures of solutions and analyses (Agg canvas, no pyplot state). Never solves."""
