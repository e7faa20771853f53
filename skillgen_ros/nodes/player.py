"""player node (placeholder until its issue lands)."""
import sys

from skillgen_ros.nodes.runtime import not_implemented


def main(args=None) -> int:
    return not_implemented("player", "see the issue tracker")


if __name__ == "__main__":
    sys.exit(main())
