"""Chapters layer: each chapter's experiments and scenarios, built from the layers below.

One module per chapter topic; lectures call these so that their cells stay short.
"""
