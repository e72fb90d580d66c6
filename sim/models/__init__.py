"""Beam models driven by a prescribed hub angle: rigid, modal (linear), modal with
geometric stiffening (third order), and the exact nonlinear finite elements."""
