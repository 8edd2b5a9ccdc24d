"""
Executables that join the ``ros`` and ``offline`` rings: the composition roots.

A node lives in ``ros/`` and writes no file; the offline code that writes files lives in
``offline/``; neither ring imports the other. A console script that needs both (a node that
writes a bag and a terrain file at its end) is put together here, and nothing in the package
imports this ring (test/package/test_architecture.py).
"""
