"""Tools around the nodes: process launching, soak runs, the monitor."""
