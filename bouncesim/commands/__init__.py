"""Sub-commands of the ``bouncesim`` CLI; shared argument helpers live in :mod:`.common`."""
