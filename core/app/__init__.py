"""The command line host: the ``agrisim`` console script, its parser of the installed commands (:mod:`agrisim.commands`) and the flags several commands share."""
