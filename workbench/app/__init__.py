"""The desktop app: an evented Session, the views subscribed to it, engine workers, and
the headless report and screenshots built from the same scene and figure builders.

``take`` and ``report`` import no Qt; the rest does.
"""
