"""Sub-commands of ``renderlab`` that live in their own module (see ``renderlab.cli.EXTRA_COMMANDS``)."""
