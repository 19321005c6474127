"""Impacts between rigid and flexible bodies (seed 002); ``exact`` holds the closed-form references."""
