"""Clean plates: the static backdrop of each input view, estimated from its own footage (docs/background.md).

``plates`` holds the estimators (numpy only), ``estimate`` runs them on one view's video (or takes a user's image),
``store`` reads and writes the plates of a scene, ``sheet`` draws the contact sheet, ``smoke_layer`` separates a
video's smoke from its plate.
"""
