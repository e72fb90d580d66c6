"""What people look at: overlays computed from a processed run, the Rerun sink and its
layout, reading ``.rrd`` files back, and the markdown + PNG report."""

import os

# Rerun's Rust side logs a file sink's failure itself (a full disk: an ERROR and a WARN
# from the file sink, an ERROR from the recording stream's flush), beside the one
# ``error:`` line the command prints for it; those targets stay quiet unless the user
# sets RUST_LOG. Set before any module of this package imports rerun (the Rust logger
# reads it once, when the bindings load).
os.environ.setdefault("RUST_LOG", "warn,re_log_encoding=off,re_sdk::recording_stream=off")
