"""What people look at: overlays computed from a processed run, the Rerun sink and its
layout, reading ``.rrd`` files back, and the markdown + PNG report."""
