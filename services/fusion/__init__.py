"""The fusion service: its core, its Zenoh loop and the adapter between the wire models and
the tracker."""
