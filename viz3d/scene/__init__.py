"""Scene files: schema, loading (with the impact shorthand), building, visuals."""


def format_reference() -> str:
    """Every key a scene file may have (``viz3d list --format``, docs/scene_format.md): the
    ordinary tables, then the impact shorthand that expands to them."""
    from viz3d.scene import hydro, shorthand, spec
    from viz3d.scene.schema import describe

    return (describe(spec.SCENE_FILE).rstrip() + "\n\n# Impact shorthand: a file with an [impactor] table has these "
            "tables instead;\n# they expand to [[bodies]] bar and impactor, [[contacts]] impact (viz3d/scene/shorthand.py)\n"
            + describe(shorthand.IMPACT_FILE).rstrip()
            + "\n\n# Hydrodynamics: a file with a [reservoir] table is a dam-reservoir study (viz3d/scene/hydro.py,\n"
            "# docs/hydro.md) and has these tables instead\n" + describe(hydro.HYDRO_FILE).rstrip() + "\n")
