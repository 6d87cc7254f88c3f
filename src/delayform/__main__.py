"""``python -m delayform`` runs the command line."""

from delayform.cli import main

if __name__ == "__main__":
    main()
