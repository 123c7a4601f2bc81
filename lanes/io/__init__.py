"""Adapters of the lanes chain: port lists, the Ushant trajectory set."""
