"""The HTML report writer and the plots every command's report draws."""
