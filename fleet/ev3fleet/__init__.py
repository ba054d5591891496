"""ev3fleet: what an operator asks of a mission record (`ev3-master --db FILE`, docs/record.md)."""
