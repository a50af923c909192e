"""A user's policy module whose import fails (`crossing-eval --policies ...plugin_raises_on_import:Any`)."""

raise RuntimeError("this plug-in needs a licence key")
