"""Every engine behind one protocol: the scene language, the Engine contract and its stepping loop, the
registry (the only table of engines), robot models, the reference, and one home per engine
(engines/<engine>/). docs/architecture.md draws the parts.
"""
