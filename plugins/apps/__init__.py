"""agrisim's applications, each a plugin behind its commands (:mod:`agrisim.plugins.apps.commands`,
the ``apps`` entry point): ``run``, ``compare`` with Tables 2 and 3, ``sweep``, ``render``,
``doctor``, ``nextview`` with its Gymnasium environment, ``traits``, ``recon`` and the rest."""
