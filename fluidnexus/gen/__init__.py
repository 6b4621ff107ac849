"""Generative backends (view synthesisers, video refiners). Heavy imports happen inside each backend."""
