"""Plumbing shared by every layer (private): thread pools, progress bars, random draws, timers,
output folders and short echoes of bad input in error messages. Imports nothing else of the
package."""
