"""ITA: Intelligent Task Automation for autonomous dimensional inspection."""

__version__ = "0.1.0"
