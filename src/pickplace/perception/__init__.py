"""What the robot senses: a depth camera over the table, and poses fitted to what it sees."""
