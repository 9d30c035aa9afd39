"""Scoring without the scene's transfer, for tests that compare a sequence's frames with
:func:`irfidelity.evaluate` of the same pair.

A sequence takes mtf and sitf from the transfer pooled over up to eight of its pairs
(:func:`irfidelity.system.scene.sequence_estimate`), a single pair from its own, so the two agree
exactly on the image components only. These tests are about the image path (masks,
registration, pairing, backends): they score both sides without the scene, which
tests/test_system.py covers on its own.
"""

#: ``**NO_SCENE``: a config option of evaluate, score_sequence and score_simulators
NO_SCENE = {"transfer_options": {"scene": False}}
